"""The ``posed`` command line. Each subcommand is a module of :mod:`posed.commands` with a
``register(subparsers)`` function; ``posed bench NAME`` runs ``bench.commands.NAME`` (loaded only then)."""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys

from posed import commands
from posed.daemon.config import EX_CONFIG
from posed.daemon.config.load import ConfigError
from posed.daemon.version import __version__


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="posed",
        description="Edge daemon: one camera -> live 3D human pose, joint angles and fall events over Zenoh.",
    )
    parser.add_argument("--version", action="version", version=f"posed {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(sub)
    return parser


def quiet_opencv() -> None:
    """OpenCV's ``[ WARN:0@...]`` lines and FFmpeg's own messages stay out of the output (posed reports what
    it cannot read itself); set these variables to see them. Before OpenCV loads, and inherited by the
    daemon's stage processes."""
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")   # AV_LOG_QUIET


def main(argv: list[str] | None = None) -> int:
    quiet_opencv()
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
