"""Dependency direction (docs/architecture.md, "The house"):

    daemon -> hal, landmarks, fitting, falls        falls -> fitting (its public result types)
    bench (offline) -> anything                     only the CLI -> bench, and lazily (inside a function)
    nothing -> daemon (but bench, which drives it)  every package -> camera_model (numpy only)

Each runtime package imports only what its layer allows; checked on the source, so a lazy import inside a
function counts too."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
STDLIB = set(sys.stdlib_module_names)
ALLOWED = {
    "camera_model": {"numpy", "camera_model"},
    "fitting": {"numpy", "numba", "fitting", "camera_model"},
    "hal": {"numpy", "cv2", "pyrealsense2", "hal", "camera_model"},
    "landmarks": {"numpy", "cv2", "onnxruntime", "landmarks", "camera_model"},
    "falls": {"numpy", "falls", "fitting", "camera_model"},
    "viz": {"numpy", "cv2", "matplotlib", "viz", "fitting", "falls", "camera_model", "client"},
    "client": {"numpy", "zenoh", "jsonschema", "referencing", "client", "fitting", "falls", "camera_model"},
}
RUNTIME = ("daemon", "hal", "landmarks", "fitting", "falls", "camera_model", "viz", "client")
# The model converter and its fetcher run only at `posed models fetch`; never in the daemon.
CONVERTER_EXTRA = {"tflite", "onnx", "flatbuffers"}
# The command line may load the offline package, inside a function, when a command needs it.
CLI = ("daemon/cli.py", "daemon/commands/")


def _root(module: str) -> str:
    """The package an import names: ``posed.fitting.result`` -> ``fitting`` (our packages by their folders),
    ``numpy.linalg`` -> ``numpy``; a bare ``posed`` is the root package, which holds no code of a layer."""
    parts = module.split(".")
    return parts[1] if parts[0] == "posed" and len(parts) > 1 else parts[0]


def imports(path: Path) -> list[tuple[str, bool]]:
    """(imported root package, at module level?) for every absolute import in ``path``."""
    tree = ast.parse(path.read_text(), str(path))
    top = set(map(id, tree.body))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(_root(alias.name), id(node) in top) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module == "posed":
            out += [(alias.name, id(node) in top) for alias in node.names]      # from posed import hal
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((_root(node.module), id(node) in top))
    return out


def violations(package: str) -> list[str]:
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        for root, module_level in sorted(set(imports(path))):
            if package in ALLOWED:
                allowed = ALLOWED[package] | STDLIB
                if package == "landmarks" and "convert" in path.parts:
                    allowed = allowed | CONVERTER_EXTRA
                if root not in allowed:
                    bad.append(f"{rel} imports {root}")
            elif root == "bench" and (module_level or not rel.startswith(CLI)):
                bad.append(f"{rel} imports bench" + (" at module level" if rel.startswith(CLI) else ""))
    return bad


@pytest.mark.parametrize("package", RUNTIME)
def test_package_imports_only_its_layer(package):
    assert (ROOT / package).is_dir()
    assert violations(package) == []


def test_nothing_but_bench_imports_daemon():
    for package in ("hal", "landmarks", "fitting", "falls", "camera_model", "viz", "client"):
        assert all(root != "daemon" for path in (ROOT / package).rglob("*.py") for root, _ in imports(path))


def test_checker_catches_a_violation(tmp_path, monkeypatch):
    pkg = tmp_path / "fitting"
    pkg.mkdir()
    (pkg / "bad.py").write_text("import numpy\ndef f():\n    from posed.daemon import config\n    import yaml\n")
    cmd = tmp_path / "daemon" / "commands"
    cmd.mkdir(parents=True)
    (cmd / "lazy.py").write_text("def f():\n    from posed.bench import fit\n")
    (cmd / "eager.py").write_text("from posed import bench\n")
    (tmp_path / "daemon" / "stage.py").write_text("def f():\n    import posed.bench.simulate\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert violations("fitting") == ["fitting/bad.py imports daemon", "fitting/bad.py imports yaml"]
    assert violations("daemon") == ["daemon/commands/eager.py imports bench at module level",
                                    "daemon/stage.py imports bench"]
