"""``posed config check FILE`` and ``posed config show``.

``check`` validates the file (every key, with its path) and then runs every check ``posed run`` makes before it
starts anything (:func:`daemon.preflight.check`: models present and verified, the native Zenoh config, the
calibration file, hook commands, the fit's row lengths): exit 0, or every problem listed and exit 78."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from dataclasses import asdict

from posed.commands import add_config_args, config_from_args
from posed.daemon.config import EX_CONFIG, load_config


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("config", help="check or show a configuration")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    check = actions.add_parser("check", help="validate a config file: exit 0, or list every problem and exit 78")
    check.add_argument("file", help="the config file to check")
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
    from posed.daemon.preflight import check

    problems = check(load_config(args.file, overrides=args.overrides))
    if problems:
        for p in problems:
            print(f"{args.file}: {p}", file=sys.stderr)
        print(f"posed: {len(problems)} problem(s); `posed run` would not start", file=sys.stderr)
        return EX_CONFIG
    print(f"{args.file}: OK")
    return 0


def _show(args: argparse.Namespace) -> int:
    print(json.dumps(asdict(config_from_args(args)), indent=2))
    return 0
