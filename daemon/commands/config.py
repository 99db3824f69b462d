"""``posed config check FILE`` and ``posed config show``."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from daemon.commands import add_config_args, config_from_args
from daemon.config import load_config


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("config", help="check or show a configuration")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    check = actions.add_parser("check", help="validate a config file: exit 0, or list every problem and exit 78")
    check.add_argument("file", help="the config file to check")
    check.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides")
    check.set_defaults(func=_check)
    show = actions.add_parser("show", help="print the effective configuration as JSON")
    add_config_args(show)
    show.set_defaults(func=_show)
    actions.add_parser("template", help="print the documented default config (config.yaml)").set_defaults(
        func=lambda a: print(__import__("daemon.config.doc").config.doc.template(), end=""))
    actions.add_parser("doc", help="print the config reference (docs/config.md)").set_defaults(
        func=lambda a: print(__import__("daemon.config.doc").config.doc.reference(), end=""))


def _check(args: argparse.Namespace) -> int:
    load_config(args.file, overrides=args.overrides)
    print(f"{args.file}: OK")
    return 0


def _show(args: argparse.Namespace) -> int:
    print(json.dumps(asdict(config_from_args(args)), indent=2))
    return 0
