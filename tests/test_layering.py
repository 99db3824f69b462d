"""Dependency direction: daemon -> hal, landmarks, fitting; nothing imports daemon; each package imports
only what its layer allows (checked on the source, so a lazy import inside a function counts too)."""

import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
STDLIB = set(sys.stdlib_module_names)
ALLOWED = {
    "fitting": {"numpy", "numba", "fitting"},
    "hal": {"numpy", "cv2", "pyrealsense2", "hal"},
    "landmarks": {"numpy", "cv2", "onnxruntime", "landmarks"},
}
# The model converter and its fetcher run only at `posed models fetch`, and its check against LiteRT (the
# test extra) only in tests and `posed bench convert`; never in the daemon.
CONVERTER_EXTRA = {"tflite", "onnx", "flatbuffers", "ai_edge_litert"}


def imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(), str(path))
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


def violations(package: str) -> list[str]:
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        allowed = ALLOWED[package] | STDLIB
        if package == "landmarks" and "convert" in path.parts:
            allowed = allowed | CONVERTER_EXTRA
        for root in sorted(imported_roots(path) - allowed):
            bad.append(f"{path.relative_to(ROOT)} imports {root}")
    return bad


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_package_imports_only_its_layer(package):
    assert (ROOT / package).is_dir()
    assert violations(package) == []


def test_checker_catches_a_violation(tmp_path, monkeypatch):
    pkg = tmp_path / "fitting"
    pkg.mkdir()
    (pkg / "bad.py").write_text("import numpy\ndef f():\n    from daemon import config\n    import yaml\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert violations("fitting") == ["fitting/bad.py imports daemon", "fitting/bad.py imports yaml"]
