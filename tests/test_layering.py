"""Dependency direction (docs/architecture.md, "The house"):

    posed/ (the command line: posed.cli, posed.commands) -> anything below it; bench only lazily (in a function)
    daemon (the service) -> hal, landmarks, fitting, falls, client, viz; never the command line, never bench
    falls -> fitting (its public result types)      bench (offline) -> anything
    client (a subscriber's library) -> fitting, falls, landmarks: the messages' own value types and parsers
    nothing -> daemon but the command line and bench   every package -> camera_model (numpy only)

Each package imports only what its layer allows; checked on the source, so a lazy import inside a function
counts too. Our own packages are named by their folders (``posed.fitting.result`` -> ``fitting``)."""

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
    "client": {"numpy", "zenoh", "jsonschema", "referencing", "client", "fitting", "falls", "landmarks",
               "camera_model"},
}
RUNTIME = ("daemon", "hal", "landmarks", "fitting", "falls", "camera_model", "viz", "client")
# The model converter and its fetcher run only at `posed models fetch`; never in the daemon.
CONVERTER_EXTRA = {"tflite", "onnx", "flatbuffers"}
# The command line's house: the folder `posed/` (the root package, posed.cli and posed.commands). It may load
# the offline package, inside a function, when a command needs it; nothing below it imports it.
CLI_HOUSE = "posed"
CLI_MODULES = {"cli", "commands", "__main__"}


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
            elif package == CLI_HOUSE:
                if root == "bench" and module_level:
                    bad.append(f"{rel} imports bench at module level")
            elif root == "bench":
                bad.append(f"{rel} imports bench")
            elif root in CLI_MODULES:
                bad.append(f"{rel} imports the command line (posed.{root})")
    return bad


@pytest.mark.parametrize("package", (*RUNTIME, CLI_HOUSE))
def test_package_imports_only_its_layer(package):
    assert (ROOT / package).is_dir()
    assert violations(package) == []


def test_the_command_line_lives_in_its_own_house():
    """``daemon/`` holds the service only: no ``posed`` subcommand is defined there."""
    assert (ROOT / CLI_HOUSE / "cli.py").is_file() and (ROOT / CLI_HOUSE / "commands" / "__init__.py").is_file()
    assert not (ROOT / "daemon" / "cli.py").exists() and not (ROOT / "daemon" / "commands").exists()
    assert not [p for p in (ROOT / "daemon").rglob("*.py") if "add_parser(" in p.read_text()]


def test_nothing_but_bench_imports_daemon():
    for package in ("hal", "landmarks", "fitting", "falls", "camera_model", "viz", "client"):
        assert all(root != "daemon" for path in (ROOT / package).rglob("*.py") for root, _ in imports(path))


def test_checker_catches_a_violation(tmp_path, monkeypatch):
    pkg = tmp_path / "fitting"
    pkg.mkdir()
    (pkg / "bad.py").write_text("import numpy\ndef f():\n    from posed.daemon import config\n    import yaml\n")
    cmd = tmp_path / "posed" / "commands"
    cmd.mkdir(parents=True)
    (cmd / "lazy.py").write_text("def f():\n    from posed.bench import fit\n")
    (cmd / "eager.py").write_text("from posed import bench\n")
    (cmd / "run.py").write_text("from posed.daemon.supervisor import Supervisor\n")
    (tmp_path / "daemon").mkdir()
    (tmp_path / "daemon" / "stage.py").write_text("def f():\n    import posed.bench.simulate\n")
    (tmp_path / "daemon" / "up.py").write_text("from posed.commands import add_config_args\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert violations("fitting") == ["fitting/bad.py imports daemon", "fitting/bad.py imports yaml"]
    assert violations("posed") == ["posed/commands/eager.py imports bench at module level"]
    assert violations("daemon") == ["daemon/stage.py imports bench",
                                    "daemon/up.py imports the command line (posed.commands)"]
