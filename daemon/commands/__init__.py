"""One module per ``posed`` subcommand, each with ``register(subparsers)``. The benchmarks run by
``posed bench NAME`` are the modules of ``bench.commands`` (each with ``add_arguments(parser)`` and
``run(args) -> int``)."""

from __future__ import annotations

import argparse

from daemon.config import Config, load_config


def add_config_args(parser: argparse.ArgumentParser, source: bool = True) -> None:
    """The options every command that reads the config takes."""
    parser.add_argument("--config", metavar="FILE", help="config file (default: the embedded config.yaml)")
    parser.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                        help="override one config key (repeatable), e.g. --set fitting.restarts=10")
    if source:
        parser.add_argument("--source", metavar="URI",
                            help="camera or recording: realsense:[SERIAL], v4l2:/dev/videoN, file:PATH")


def config_from_args(args: argparse.Namespace) -> Config:
    """Load the config named by the common options (raises ConfigError listing every problem)."""
    return load_config(args.config, overrides=args.overrides, source=getattr(args, "source", None))
