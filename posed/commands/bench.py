"""``posed bench NAME [--json] [OPTIONS]``: the benchmarks (speed, accuracy, memory targets live here, not in
tests). The benchmarks are offline code in the top-level ``bench`` package; it is loaded only when a benchmark
is run (listing the names reads the folder, it imports nothing)."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import io
import json
import pkgutil
import sys
from pathlib import Path


def names() -> list[str]:
    """The benchmark names: the modules of ``bench.commands``, found without importing them."""
    spec = importlib.util.find_spec("posed.bench")
    if spec is None or not spec.submodule_search_locations:
        return []
    folder = Path(next(iter(spec.submodule_search_locations))) / "commands"
    return sorted(m.name for m in pkgutil.iter_modules([str(folder)]) if not m.name.startswith("_"))


def register(sub: argparse._SubParsersAction) -> None:
    known = names()
    parser = sub.add_parser("bench", help="run a benchmark and print its numbers",
                            description=f"benchmarks: {', '.join(known)}; `posed bench NAME --help` for options")
    parser.add_argument("name", choices=known, metavar="NAME", help=", ".join(known))
    parser.add_argument("options", nargs=argparse.REMAINDER, help="the benchmark's own options")
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    module = importlib.import_module(f"posed.bench.commands.{args.name}")
    parser = argparse.ArgumentParser(prog=f"posed bench {args.name}",
                                     description=(module.__doc__ or "").strip().split("\n")[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    module.add_arguments(parser)
    options = parser.parse_args(args.options)
    if not options.json:
        return int(module.run(options) or 0)
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            code = int(module.run(options) or 0)
    finally:
        sys.stdout.write(with_version(out.getvalue()))
        sys.stdout.flush()
    return code


def with_version(text: str) -> str:
    """A benchmark's ``--json`` output with ``posed_version`` added to its JSON object (or to each JSON-object
    line); anything else is passed on unchanged."""
    from posed.daemon.version import __version__

    def tag(obj):
        return {"posed_version": __version__, **obj} if isinstance(obj, dict) else obj

    try:
        obj = json.loads(text)
    except ValueError:
        lines = []
        for line in text.splitlines(keepends=True):
            try:
                parsed = json.loads(line)
            except ValueError:
                lines.append(line)
                continue
            lines.append(json.dumps(tag(parsed)) + "\n")
        return "".join(lines)
    indent = 2 if text.lstrip().startswith("{\n") else None
    return json.dumps(tag(obj), indent=indent) + "\n"
