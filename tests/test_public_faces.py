"""Public faces (docs/architecture.md, "The house"): fitting, landmarks and hal each export what other packages
use from their ``__init__``, and posed/ (the command line), daemon/, falls/ and bench/ import only those names, from the package itself,
never an inner module. The model converter ``landmarks.convert`` is a public subpackage with its own
``__all__``. Checked on the source, so an import inside a function counts too; so does ``hal.recorder.x``
after ``from posed import hal``. Modules are named here by their folders (``fitting.result`` is ``posed.fitting.result``).

``from posed import fitting, landmarks`` stays cheap: their names load on first use, so neither the
command line nor a package that needs only a result type pays for numba or onnxruntime."""

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CLIENTS = ("posed", "daemon", "falls", "bench")   # posed/: the command line
PACKAGES = ("fitting", "landmarks", "hal")
SUBPACKAGES = ("landmarks.convert",)  # public too, with their own __all__
FACES = PACKAGES + SUBPACKAGES


def _init(module: str) -> Path:
    return ROOT.joinpath(*module.split(".")) / "__init__.py"


def declared_all(module: str) -> list[str]:
    """The literal ``__all__`` of a package's ``__init__.py``, read without importing it."""
    for node in ast.parse(_init(module).read_text()).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__"
                                                for t in node.targets):
            return list(ast.literal_eval(node.value))
    raise AssertionError(f"{module} has no __all__")


def inner_modules(module: str) -> set[str]:
    """The modules and subpackages of a package that are not public."""
    d = _init(module).parent
    names = {p.stem for p in d.glob("*.py") if p.stem != "__init__"}
    names |= {p.parent.name for p in d.glob("*/__init__.py")}
    return {n for n in names if f"{module}.{n}" not in FACES}


PUBLIC = {m: set(declared_all(m)) for m in FACES}
INNER = {m: inner_modules(m) for m in FACES}


def _dotted(node: ast.expr, bound: dict[str, str]) -> str | None:
    if isinstance(node, ast.Name):
        return bound.get(node.id)
    if isinstance(node, ast.Attribute):
        base = _dotted(node.value, bound)
        return None if base is None else f"{base}.{node.attr}"
    return None


def _short(module: str) -> str:
    """``posed.fitting.result`` -> ``fitting.result``: the checks speak of the packages by their folders."""
    return module.removeprefix("posed.")


def file_violations(path: Path, rel: str) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    bad = []
    bound: dict[str, str] = {}  # name bound by `from posed import hal` (or `... as h`) -> the package
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module == "posed":
            # `from posed import hal` binds the package as `import hal` did
            node = ast.Import(names=[ast.alias(a.name, a.asname) for a in node.names], lineno=node.lineno)
        if isinstance(node, ast.Import):
            for alias in node.names:
                alias = ast.alias(_short(alias.name), alias.asname)
                if alias.name.split(".")[0] not in PACKAGES:
                    continue
                if alias.name not in FACES:
                    bad.append(f"{rel}:{node.lineno}: import {alias.name}")
                elif alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    root = alias.name.split(".")[0]
                    bound[root] = root
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            module = _short(node.module)
            if module.split(".")[0] not in PACKAGES:
                continue
            names = [a.name for a in node.names]
            if module not in FACES:
                bad.append(f"{rel}:{node.lineno}: from {module} import {', '.join(names)}")
                continue
            hidden = [n for n in names if n not in PUBLIC[module] and f"{module}.{n}" not in FACES]
            if hidden:
                bad.append(f"{rel}:{node.lineno}: from {module} import {', '.join(hidden)}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            base = _dotted(node.value, bound)
            if base in FACES and node.attr in INNER[base]:
                bad.append(f"{rel}:{node.lineno}: {base}.{node.attr}")
    return bad


def violations(root: Path = ROOT) -> list[str]:
    """Every import (or attribute use) of an inner module of fitting, landmarks or hal in posed/ (the
    command line), daemon/, falls/ and bench/ under ``root``, as ``file:line: import``."""
    bad = []
    for client in CLIENTS:
        for path in sorted((root / client).rglob("*.py")):
            bad += file_violations(path, path.relative_to(root).as_posix())
    return sorted(bad)


def test_clients_import_only_the_public_faces():
    assert (ROOT / "daemon").is_dir() and (ROOT / "bench").is_dir() and (ROOT / "falls").is_dir()
    assert violations() == []


def test_checker_catches_a_violation(tmp_path):
    (tmp_path / "posed" / "commands").mkdir(parents=True)
    (tmp_path / "daemon").mkdir()
    (tmp_path / "falls").mkdir()
    (tmp_path / "bench").mkdir()
    (tmp_path / "daemon" / "a.py").write_text(
        "from posed.fitting.result import FitResult\nfrom posed.fitting import Fitter\n")
    (tmp_path / "posed" / "commands" / "b.py").write_text(
        "def f():\n"
        "    from posed.landmarks.recording import LandmarkFrame\n"
        "    from posed.landmarks.convert import fetch_models\n"
        "    from posed.landmarks.convert.fetch import FetchError\n"
        "    from posed.landmarks import convert, PoseLandmarker\n")
    (tmp_path / "bench" / "c.py").write_text(
        "from posed import hal\nimport posed.fitting.kernels\nfrom posed.hal import registry, open_source\n"
        "hal.recorder.check_output('x.mp4')\nhal.open_source('file:x.mp4')\n")
    (tmp_path / "falls" / "d.py").write_text("from posed.fitting import BODY_LANDMARKS, kernels as K\n")
    (tmp_path / "falls" / "e.py").write_text("def f(landmarks, hal):\n    return landmarks.shape, hal.recorder\n")
    assert violations(tmp_path) == [
        "bench/c.py:2: import fitting.kernels",
        "bench/c.py:3: from hal import registry",
        "bench/c.py:4: hal.recorder",
        "daemon/a.py:1: from fitting.result import FitResult",
        "falls/d.py:1: from fitting import kernels",
        "posed/commands/b.py:2: from landmarks.recording import LandmarkFrame",
        "posed/commands/b.py:4: from landmarks.convert.fetch import FetchError",
    ]


def _module(name: str):
    if name == "landmarks.convert":
        pytest.importorskip("tflite")
        pytest.importorskip("onnx")
    return importlib.import_module(f"posed.{name}")


@pytest.mark.parametrize("name", FACES)
def test_every_public_name_resolves(name):
    module = _module(name)
    assert module.__all__ == declared_all(name)
    assert len(set(module.__all__)) == len(module.__all__)
    for public in module.__all__:
        assert getattr(module, public) is not None, public
    assert set(module.__all__) <= set(dir(module))
    with pytest.raises(AttributeError):
        module.no_such_name  # noqa: B018


def static_names(module: str) -> dict[str, tuple[str, str]]:
    """What a type checker sees: public name -> (module, name) for the imports at module level of a package's
    ``__init__.py``, those under ``if TYPE_CHECKING:`` included."""
    out = {}
    for node in ast.parse(_init(module).read_text()).body:
        body = [node]
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            body = node.body
        for stmt in body:
            if isinstance(stmt, ast.ImportFrom) and stmt.module:
                out |= {a.asname or a.name: (stmt.module, a.name) for a in stmt.names}
    return out


@pytest.mark.parametrize("name", FACES)
def test_type_checkers_see_the_same_names(name):
    module = _module(name)
    seen = static_names(name)
    assert set(module.__all__) <= set(seen)
    for public in module.__all__:
        source, attr = seen[public]
        assert getattr(module, public) is getattr(importlib.import_module(source), attr), public


def _loaded_after(code: str) -> list[str]:
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(m for m in HEAVY if m in sys.modules)))"
    out = subprocess.run([sys.executable, "-c", f"HEAVY = {HEAVY!r}\n{probe}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, check=True).stdout
    return json.loads(out.splitlines()[-1])


HEAVY = ("numba", "onnxruntime", "posed.fitting.fitter", "posed.landmarks.pipeline", "posed.landmarks.runtime")


def test_importing_fitting_and_landmarks_loads_neither_numba_nor_onnxruntime():
    assert _loaded_after("from posed import fitting, landmarks") == []
    # what the config, the messages and falls take from them
    assert _loaded_after("from posed import fitting, landmarks\nfitting.FitResult, fitting.FitConfig, "
                         "fitting.BODY_LANDMARKS, landmarks.LandmarkFrame, landmarks.LandmarkConfig") == []


def test_the_command_line_loads_neither_numba_nor_onnxruntime():
    assert _loaded_after("import posed.cli\nposed.cli.build_parser()") == []
