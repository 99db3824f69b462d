"""``posed resume [--by NAME] [--robot R]``: ask the running daemon to end its pause for privacy now and watch
again (always allowed; nothing happens when none runs). The query, the answer and the exit status are
``posed pause``'s (:mod:`posed.commands.pause`) with a duration of 0."""

from __future__ import annotations

import argparse

from posed.commands.pause import add_common_args, ask


def register(sub: argparse._SubParsersAction) -> None:
    resume = sub.add_parser("resume", help="end a pause for privacy now: watch again",
                            description="Asks the running daemon to end its pause for privacy now (always "
                                        "allowed; nothing happens when none runs).")
    add_common_args(resume)
    resume.set_defaults(func=run_resume)


def run_resume(args: argparse.Namespace) -> int:
    return ask(args, "posed resume", 0.0)
