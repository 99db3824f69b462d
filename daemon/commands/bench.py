"""``posed bench NAME [--json]``: the benchmarks (speed, accuracy, memory targets live here, not in tests)."""

from __future__ import annotations

import argparse
import importlib
import pkgutil

from daemon import commands


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("bench", help="run a benchmark and print its numbers")
    sub_benches = parser.add_subparsers(dest="bench", metavar="NAME", required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if not info.name.startswith("bench_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        bench = sub_benches.add_parser(info.name[len("bench_"):], help=(module.__doc__ or "").strip().split("\n")[0])
        bench.add_argument("--json", action="store_true", help="print one JSON object")
        module.add_arguments(bench)
        bench.set_defaults(func=module.run)
