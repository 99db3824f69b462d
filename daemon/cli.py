"""The ``posed`` command line. Each subcommand is a module of :mod:`daemon.commands` with a
``register(subparsers)`` function; ``posed bench NAME`` runs ``bench.commands.NAME`` (loaded only then)."""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from daemon import commands
from daemon.config import EX_CONFIG
from daemon.config.load import ConfigError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="posed",
        description="Edge daemon: one camera -> live 3D human pose, joint angles and fall events over Zenoh.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(str(exc), file=sys.stderr)
        print(f"posed: {len(exc.problems)} problem(s) in the configuration; nothing was started", file=sys.stderr)
        return EX_CONFIG
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
