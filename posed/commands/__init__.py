"""One module per ``posed`` subcommand, each with ``register(subparsers)``. The benchmarks run by
``posed bench NAME`` are the modules of ``bench.commands`` (each with ``add_arguments(parser)`` and
``run(args) -> int``)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from posed.daemon.config import Config, load_config
from posed.daemon.config.paths import config_file

CONFIG_HELP = ("config file (default: $POSED_CONFIG, else /etc/posed/config.yaml when it exists, else the "
               "embedded default)")


def add_config_args(parser: argparse.ArgumentParser, source: bool = True,
                    example: str = "fitting.restarts=10") -> None:
    """The options every command that reads the config takes; ``example`` is a ``--set`` the command uses."""
    parser.add_argument("--config", metavar="FILE", help=CONFIG_HELP)
    parser.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                        help=f"override one config key (repeatable), e.g. --set {example}")
    if source:
        parser.add_argument("--source", metavar="URI",
                            help="camera or recording: realsense:[SERIAL], v4l2:/dev/videoN, "
                                 "file:PATH[?loop=true&realtime=false]")


def config_path(args: argparse.Namespace) -> Path | None:
    """The config file the command reads (see :mod:`daemon.config.paths`); None: the embedded default."""
    return config_file(getattr(args, "config", None))


def config_from_args(args: argparse.Namespace) -> Config:
    """Load the config named by the common options (raises ConfigError listing every problem)."""
    return load_config(config_path(args), overrides=getattr(args, "overrides", ()),
                       source=getattr(args, "source", None))


def error_printer(command: str) -> Callable[[str], None]:
    """The commands' error line: ``print(f"{command}: {msg}")`` on stderr, flushed."""
    def err(msg: str) -> None:
        print(f"{command}: {msg}", file=sys.stderr, flush=True)
    return err


def read_jsonl(path: str, parse: Callable[[object], object]) -> tuple[list, int]:
    """``parse`` of every JSON line of ``path`` (blank lines skipped) and how many lines could not be parsed:
    each is reported on stderr as ``PATH:LINE: what is wrong`` and skipped. OSError when the file cannot be
    read: the caller says so."""
    import json

    items, problems = [], 0
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                items.append(parse(json.loads(line)))
            except (ValueError, KeyError, TypeError) as exc:   # json.JSONDecodeError is a ValueError
                print(f"{path}:{lineno}: {exc}", file=sys.stderr)
                problems += 1
    return items, problems
