"""The wheel: built offline from a copy of the tree (``pip wheel --no-deps --no-build-isolation``), it holds every
module and data file of the packages, the licence and the ``posed`` script; installed into a fresh venv (its
dependencies taken from the project's venv through a path entry, never the project's own source), ``posed``
runs from it with the embedded default config and no file beside it, and ``posed demo`` works."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
IGNORE = shutil.ignore_patterns(".venv", ".git", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache",
                                ".ruff_cache", "*.pyc", "*.nbi", "*.nbc")


def _package_dirs() -> dict[str, str]:
    """What pyproject.toml ships: import package -> its folder in the checkout (``posed.daemon`` -> ``daemon``),
    through its ``package-dir`` map (the longest mapped prefix wins, as in setuptools)."""
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapped = tool["package-dir"]
    out = {}
    for pkg in tool["packages"]:
        base = max((k for k in mapped if pkg == k or pkg.startswith(k + ".")), key=len)
        out[pkg] = "/".join([mapped[base], *pkg[len(base):].split(".")[1:]])
    return out


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=IGNORE)
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "--no-index",
                        "-w", str(tmp / "dist"), str(src)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    (whl,) = (tmp / "dist").glob("posed-*.whl")
    return whl


def test_every_folder_with_code_is_shipped_as_part_of_posed():
    """A new package (a folder with __init__.py) must be added to [tool.setuptools] packages (and a new
    top-level folder to package-dir), or the wheel lacks it; every shipped package is ``posed`` or under it."""
    dirs = _package_dirs()
    assert all(pkg == "posed" or pkg.startswith("posed.") for pkg in dirs), sorted(dirs)
    assert all((ROOT / d / "__init__.py").is_file() for d in dirs.values()), dirs
    code = {init.parent.relative_to(ROOT).as_posix() for init in ROOT.rglob("__init__.py")
            if not {".venv", "tests", "build", ".git"} & set(init.relative_to(ROOT).parts)}
    missing = sorted(code - set(dirs.values()))
    assert not missing, f"add to [tool.setuptools] packages (and package-dir): {missing}"


def test_the_wheel_holds_every_module_data_file_licence_and_script(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = []
    for pkg, folder in _package_dirs().items():
        for path in (ROOT / folder).iterdir():
            if path.is_file() and path.suffix not in (".pyc", ".nbi", ".nbc"):
                expected.append("/".join([*pkg.split("."), path.name]))   # modules and the data the code opens
        for sub in (ROOT / folder).iterdir():               # data folders (schemas/, static/): no __init__.py
            if sub.is_dir() and not (sub / "__init__.py").is_file() and sub.name != "__pycache__":
                expected += ["/".join([*pkg.split("."), f.relative_to(ROOT / folder).as_posix()])
                             for f in sub.rglob("*") if f.is_file() and "__pycache__" not in f.parts]
    missing = sorted(set(expected) - names)
    assert not missing, f"not in the wheel (package-data in pyproject.toml?): {missing[:20]}"
    assert not [n for n in names if "__pycache__" in n or n.endswith((".nbi", ".nbc"))]
    # what the code opens beside its modules: the fitting kernels' sources (hashed by fitting.jitcache), the
    # MediaPipe peer script of `posed bench peer`
    assert {"posed/fitting/udeas.py", "posed/fitting/refine.py", "posed/bench/commands/_mediapipe_peer.py"} <= names
    dist_info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA"))
    meta = zipfile.ZipFile(wheel).read(f"{dist_info}/METADATA").decode()
    assert "License-Expression: Apache-2.0" in meta
    from posed.daemon.version import __version__

    assert f"\nVersion: {__version__}\n" in meta and wheel.name.startswith(f"posed-{__version__}-")
    licence = zipfile.ZipFile(wheel).read(f"{dist_info}/licenses/LICENSE").decode()
    assert licence == (ROOT / "LICENSE").read_text() and "Apache License" in licence and "Version 2.0" in licence
    assert "posed = posed.cli:main" in zipfile.ZipFile(wheel).read(f"{dist_info}/entry_points.txt").decode()


def test_the_wheel_adds_one_top_level_import_package_posed(wheel):
    """A robot's site-packages holds ROS tools, vendor SDKs and other daemons: posed adds ``posed`` and nothing
    else (no ``daemon``, ``client`` or ``bench`` to clash with theirs)."""
    names = zipfile.ZipFile(wheel).namelist()
    roots = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert roots == {"posed"}, sorted(roots)
    dist_info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA"))
    top_level = f"{dist_info}/top_level.txt"
    if top_level in names:
        assert zipfile.ZipFile(wheel).read(top_level).decode().split() == ["posed"]


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """A fresh venv holding only the wheel; the dependencies come from the project's venv by a path entry
    (a plain path in a .pth is not a site dir: the project's editable-install hook there is not run)."""
    venv = tmp_path_factory.mktemp("venv") / "v"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    py = venv / "bin" / "python"
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps", "--no-index",
                        str(wheel)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    site = Path(subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "zz_project_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv


def _environ(env: dict | None = None) -> dict:
    return {**{k: v for k, v in os.environ.items() if k not in ("POSED_CONFIG", "PYTHONPATH")}, **(env or {})}


def _posed(venv: Path, *args: str, env: dict | None = None, timeout: float = 120):
    return subprocess.run([str(venv / "bin" / "posed"), *args], capture_output=True, text=True, timeout=timeout,
                          cwd=venv, env=_environ(env))


@pytest.fixture(scope="module")
def numba_cache(tmp_path_factory) -> Path:
    """One numba cache for the installed wheel's processes (`posed warmup` fills it once)."""
    return tmp_path_factory.mktemp("numba")


def test_every_command_runs_from_the_installed_wheel(installed):
    from posed.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    modules = {m.stem for m in (ROOT / "posed" / "commands").glob("[!_]*.py")}
    assert set(sub.choices) == modules, sorted(set(sub.choices) ^ modules)
    for name in sub.choices:
        r = _posed(installed, name, "--help")
        assert r.returncode == 0 and r.stdout.startswith(f"usage: posed {name}"), (name, r.stdout + r.stderr)
    r = subprocess.run([str(installed / "bin" / "python"), "-m", "posed", "--version"], capture_output=True,
                       text=True, cwd=installed, env=_environ(), timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("posed "), r.stderr


def test_the_installed_wheel_runs_from_its_own_files(installed):
    r = _posed(installed, "--version")
    from posed.daemon.version import __version__

    assert r.returncode == 0 and r.stdout.splitlines()[0] == f"posed {__version__}", r.stdout + r.stderr
    assert r.stdout.splitlines()[1].startswith("landmark models: "), r.stdout     # which models it runs
    where = subprocess.run([str(installed / "bin" / "python"), "-c", "from posed import daemon, fitting; "
                            "print(daemon.__file__); print(fitting.__file__)"],
                           capture_output=True, text=True, cwd=installed, check=True).stdout.split()
    assert all(str(installed) in w for w in where), where          # not the checkout
    r = _posed(installed, "config", "template")
    from posed.daemon.config.doc import template

    assert r.returncode == 0 and r.stdout == template(), r.stderr
    show = _posed(installed, "config", "show", "--set", "robot_id=wheel")
    assert show.returncode == 0, show.stderr                      # no config.yaml beside the package: embedded
    assert '"robot_id": "wheel"' in show.stdout


@pytest.mark.slow
@pytest.mark.timeout(1000)
def test_models_verify_and_demo_from_the_installed_wheel(installed, tmp_path, shared_data, numba_cache):
    """`posed models verify` and `posed demo` from the wheel, on the models `make` fetched (`posed models fetch`
    from a wheel needs the `convert` extra, as the README says; its error names it)."""
    from posed.landmarks import default_models_dir

    env = {"POSED_MODELS_DIR": str(default_models_dir(None)), "POSED_SHARED_DATA": str(shared_data),
           "NUMBA_CACHE_DIR": str(numba_cache)}
    r = _posed(installed, "models", "verify", env=env)
    assert r.returncode == 0 and "intact" in r.stdout, r.stdout + r.stderr
    r = _posed(installed, "warmup", env=env, timeout=600)       # what deploy/install.sh and `make` do
    assert r.returncode == 0 and "a new process loads them in" in r.stdout, r.stdout + r.stderr
    r = _posed(installed, "demo", "--seconds", "2", env={**env, "TMPDIR": str(tmp_path)}, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines()[-1].startswith("posed demo:") and "daemon exit status 0" in r.stdout
    assert not list(tmp_path.glob("posed-demo-*")), "posed demo left its temporary state behind"


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_the_client_and_ros2_examples_run_from_the_installed_wheel(installed, tmp_path, shared_data, numba_cache):
    """docs/client.md's and docs/ros2.md's examples, as written, with the wheel's Python against `posed run`
    from the wheel (ROS 2 enabled) replaying a real fall through a router on 127.0.0.1."""
    from tests.daemon.zenoh_util import free_port, router
    from tests.interop.daemons import URFD, Daemon, fall_overrides, wait_for
    from tests.interop.test_client import doc_example

    py = str(installed / "bin" / "python")
    env = _environ({"NUMBA_CACHE_DIR": str(numba_cache), "ROS_DOMAIN_ID": "0"})
    port = free_port()
    rep = f"tcp/127.0.0.1:{port}"
    r = router(rep)
    d = Daemon(tmp_path, "wheel1", shared_data / URFD / "urfd_02_fall.landmarks.jsonl", rep,
               *fall_overrides(shared_data), "source.loop=true", "source.realtime=true", "ros2.enabled=true",
               python=py, cwd=installed, env=env)
    try:
        d.start()
        code = doc_example().replace("tcp/127.0.0.1:7447", rep)

        def client_example():
            out = subprocess.run([py, "-c", code], cwd=installed, env=env, capture_output=True, text=True,
                                 timeout=120)
            assert out.returncode == 0, out.stderr[-2000:]
            return out.stdout if re.search(r"^wheel1 \d+ ", out.stdout, re.M) else None

        text = wait_for(client_example, 400, "poses printed by docs/client.md's example", d)
        assert "robots up: ['wheel1']" in text
        ros = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "ros2.md").read_text(), re.S)[0]
        out = subprocess.run([py, "-c", ros.replace("router_port=7447", f"router_port={port}")], cwd=installed,
                             env=env, capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        lines = [x for x in out.stdout.splitlines() if x.strip()]
        assert lines and "_joint':" in lines[-1], out.stdout[-2000:] + out.stderr[-2000:]   # URDF-style names
    finally:
        d.stop()
        r.close()
