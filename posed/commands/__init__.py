"""One module per ``posed`` subcommand, each with ``register(subparsers)``. The benchmarks run by
``posed bench NAME`` are the modules of ``bench.commands`` (each with ``add_arguments(parser)`` and
``run(args) -> int``)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from posed.daemon.config import EX_CONFIG, Config, load_config
from posed.daemon.config.load import ConfigError, key_covers
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
    return load_labelled(config_path(args), getattr(args, "overrides", ()), getattr(args, "source", None))


def load_labelled(path: str | Path | None, overrides=(), source: str | None = None) -> Config:
    """``load_config``, with each problem blamed on where it comes from: the ``--set`` that made it, ``--source``,
    or the file (``the embedded default config`` when no file was read), not on ``config.yaml`` alone."""
    try:
        return load_config(path, overrides=overrides, source=source)
    except ConfigError as exc:
        raise LabelledConfigError(exc, path, overrides, source) from None


class LabelledConfigError(ConfigError):
    """A ConfigError whose lines say, problem by problem, whether a ``--set``, ``--source`` or the file made it."""

    def __init__(self, exc: ConfigError, path, overrides, source) -> None:
        super().__init__(exc.problems, exc.origin)
        self.__dict__.update(exc.__dict__)      # whatever else the loader put on it (e.g. the partial config)
        file_label = exc.origin if path is not None else "the embedded default config"
        lines = []
        for p in self.problems:
            origin = _override_for(p.path, overrides)
            if origin is None and p.path == "--set":
                origin = "--set"
            elif origin is None and source and (p.path == "source" or p.path.startswith("source.")
                                                or p.path == "--source"):
                origin = f"--source {source}"
            text = str(p)
            if origin == "--set" and text.startswith("--set: "):
                text = text[len("--set: "):]
            lines.append(f"{origin or file_label}: {text}")
        self.args = ("\n".join(lines),)


def config_problems(exc: ConfigError, label) -> int:
    """Print a config's problems and those the start-up checks find in what could be read of it
    (``daemon.preflight.partial_problems``; ``label`` formats each of those), the count, and return 78: what
    ``posed run`` and ``posed config check`` say of a config that cannot start the daemon."""
    from posed.daemon.preflight import partial_problems

    more = partial_problems(exc)
    print(str(exc), file=sys.stderr)
    for p in more:
        print(label(p), file=sys.stderr)
    print(f"posed: {len(exc.problems) + len(more)} problem(s) in the configuration; nothing was started",
          file=sys.stderr)
    return EX_CONFIG


def _override_for(key: str, overrides) -> str | None:
    """``--set K=V`` when the problem at ``key`` was made by that override (the last one that touches it)."""
    for assignment in reversed(list(overrides)):
        name = ".".join(p for p in assignment.partition("=")[0].strip().split(".") if p)
        if name and key_covers(key, name):
            return f"--set {assignment}"
    return None


def positive_int(text: str) -> int:
    """An argparse type: a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} must be at least 1")
    return value


def bounded_float(low: float, high: float, unit: str = ""):
    """An argparse type: a finite number above ``low`` and at most ``high``."""
    import math

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(value) or not low < value <= high:
            raise argparse.ArgumentTypeError(f"{text} is out of range: more than {low:g} and at most {high:g}"
                                             + (f" {unit}" if unit else ""))
        return value
    return parse


def bounded_int(low: int, high: int, unit: str = ""):
    """An argparse type: a whole number from ``low`` to ``high``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text} is out of range: from {low} to {high}"
                                             + (f" {unit}" if unit else ""))
        return value
    return parse


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
