"""``posed config check [FILE] [--source URI]`` and ``posed config show``.

``check`` validates the file (every key, with its path) and then runs every check ``posed run`` makes before it
starts anything (:func:`daemon.preflight.check`: models present and verified, the native Zenoh config, the
calibration file, hook commands, the fit's row lengths): exit 0, or every problem listed and exit 78. With
``--source URI`` it also opens that source, reads its first frame and prints its size, orientation and rate
and what the daemon will do with it (``posed.commands._probe``); a source that gives no frame is a problem."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from dataclasses import asdict

from posed.commands import add_config_args, config_from_args, config_problems, load_labelled
from posed.daemon.config import EX_CONFIG
from posed.daemon.config.load import ConfigError


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("config", help="check or show a configuration")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    check = actions.add_parser("check", help="validate a config file: exit 0, or list every problem and exit 78")
    check.add_argument("file", nargs="?", help="the config file to check (default: $POSED_CONFIG, else "
                                                "/etc/posed/config.yaml when it exists, else the embedded default)")
    check.add_argument("--source", metavar="URI",
                       help="also probe this camera or recording (realsense:[SERIAL], v4l2:/dev/videoN, file:PATH): "
                            "print its size, rate and orientation and what the daemon will do with it")
    check.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                       help="check the file with this override applied (repeatable), e.g. --set robot_id=kitchen")
    check.set_defaults(func=_check)
    show = actions.add_parser("show", help="print the effective configuration as JSON")
    add_config_args(show)
    show.set_defaults(func=_show)
    actions.add_parser("template", help="print the documented default config (config.yaml)").set_defaults(
        func=lambda a: print(importlib.import_module("posed.daemon.config.doc").template(), end=""))
    actions.add_parser("doc", help="print the config reference (docs/config.md)").set_defaults(
        func=lambda a: print(importlib.import_module("posed.daemon.config.doc").reference(), end=""))


def _check(args: argparse.Namespace) -> int:
    from posed.daemon.config.paths import config_file, state_dir
    from posed.daemon.preflight import check, hook_program_problems, model_provenance_problems
    from posed.daemon.state_check import state_dir_problems

    path = args.file if args.file else config_file(None)
    name = str(path) if path else "(the embedded default config)"
    try:
        cfg = load_labelled(path, args.overrides, args.source)   # a problem is blamed on its --set, not the file
    except ConfigError as exc:      # the start-up checks still run on what could be read: every problem at once
        return config_problems(exc, lambda p: f"{name}: {p}")
    problems = check(cfg)
    stopping = len(problems)            # these stop `posed run`; a failing state dir only degrades it
    problems += (state_dir_problems(state_dir(cfg.pipeline)) + hook_program_problems(cfg)
                 + model_provenance_problems(cfg))
    lines: list[str] = []
    if args.source and not stopping:
        from posed.commands._probe import probe
        from posed.daemon.preflight import resolve_source

        lines, more = probe(resolve_source(cfg, lambda p: p))
        problems += more
        stopping += len(more)
    if problems:
        for p in problems:
            print(f"{name}: {p}", file=sys.stderr)
        print(f"posed: {len(problems)} problem(s); `posed run` would " + (
            "not start" if stopping else "start, degraded as said above"),
            file=sys.stderr)
        return EX_CONFIG
    for line in lines:
        print(line)
    print(f"{name}: OK")
    return 0


def _show(args: argparse.Namespace) -> int:
    print(json.dumps(asdict(config_from_args(args)), indent=2))
    return 0
