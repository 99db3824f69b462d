"""``posed events [--since T] [--until T] [--limit N] [--unacked] [--json]``: list stored fall events."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from daemon.commands import add_config_args, config_from_args
from daemon.config.paths import events_path
from daemon.timeparse import parse_time


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("events", help="list the fall events stored in the journal (state dir)")
    add_config_args(parser, source=False)
    parser.add_argument("--since", metavar="TIME", help="from this time: 2h, 7d, today, 2024-05-01T14:00, ...")
    parser.add_argument("--until", metavar="TIME", help="up to this time (same forms as --since)")
    parser.add_argument("--limit", type=int, default=None, metavar="N",
                        help="only the newest N messages (of those --unacked and the times select)")
    parser.add_argument("--unacked", action="store_true", help="only messages not yet acknowledged")
    parser.add_argument("--journal", metavar="FILE", help="journal file (default: events.sqlite3 in the state dir)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from daemon.outbox.journal import EventJournal, JournalError  # not at import: it pulls in structlog

    try:
        since = parse_time(args.since) if args.since else None
        until = parse_time(args.until) if args.until else None
    except ValueError as exc:
        print(f"posed events: {exc}", file=sys.stderr)
        return 2
    path = Path(args.journal) if args.journal else events_path(config_from_args(args).pipeline)
    if not path.is_file():
        if args.json:
            print(json.dumps({"journal": str(path), "events": []}))
        else:
            print(f"no event journal at {path} yet (the daemon creates it with its first fall event)")
        return 0
    try:
        with EventJournal(path, readonly=True) as journal:
            stored = journal.query(since, until, args.limit, unacked=args.unacked)
    except (JournalError, FileNotFoundError) as exc:
        print(f"posed events: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps({"journal": str(path), "events": [s.to_json() for s in stored]}))
        return 0
    if not stored:
        print(f"no events in {path} for that time range")
        return 0
    print(f"{'wall time (UTC)':<24} {'event':<12} {'state':<10} {'conf':>5} {'pub':>3} {'ack':>3}  features")
    for s in stored:
        e = s.event
        print(f"{e.wall_time[:23]:<24} {e.id[:12]:<12} {e.state:<10} {e.confidence:5.2f} "
              f"{'yes' if s.published_at else 'no':>3} {'yes' if s.acked_at else 'no':>3}  {','.join(e.features)}")
    return 0
