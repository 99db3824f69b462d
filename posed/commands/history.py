"""``posed history [--since T] [--until T] [--csv] [-o FILE]``: export the stored joint angles."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from posed.commands import add_config_args, config_from_args, config_path
from posed.daemon.config.paths import HISTORY_FILE, reading_state_dir
from posed.daemon.timeparse import iso, parse_time

if TYPE_CHECKING:
    from posed.daemon.config.sections import PipelineConfig
    from posed.daemon.history.store import AngleHistory


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("history", help="export or summarise the stored joint-angle history")
    add_config_args(parser, source=False, example="pipeline.state_dir=/var/lib/posed")
    add_range_args(parser)
    parser.add_argument("--csv", action="store_true", help="write CSV (one row per kept frame)")
    parser.add_argument("-o", "--output", metavar="FILE", help="write to FILE instead of stdout")
    parser.set_defaults(func=run)


def add_range_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--since", metavar="TIME", help="from this time: 2h, 7d, today, 2024-05-01T14:00, ...")
    parser.add_argument("--until", metavar="TIME", help="up to this time (same forms as --since)")
    parser.add_argument("--db", metavar="FILE", help="history file (default: history.sqlite3 in the state dir)")


def open_history(args: argparse.Namespace, pipeline: PipelineConfig | None = None
                 ) -> tuple[AngleHistory, float | None, float | None]:
    """Parse --since/--until/--db and open the history read-only (raises ValueError/FileNotFoundError).

    ``pipeline``: the config's pipeline section when the caller has loaded it (else it is loaded here when
    there is no --db)."""
    from posed.daemon.history.store import AngleHistory  # not at import: it pulls in structlog

    since = parse_time(args.since) if args.since else None
    until = parse_time(args.until) if args.until else None
    if args.db:
        path = Path(args.db)
    else:
        path = history_path(pipeline if pipeline is not None else config_from_args(args).pipeline,
                            config_path(args))
    return AngleHistory(path, readonly=True), since, until


def history_path(pipeline: PipelineConfig, config_file: Path | None) -> Path:
    """history.sqlite3 in the state dir a reading command opens (the service's when it is the one in use)."""
    return reading_state_dir(pipeline, config_file, HISTORY_FILE) / HISTORY_FILE


def run(args: argparse.Namespace) -> int:
    try:
        hist, since, until = open_history(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"posed history: {exc}", file=sys.stderr)
        return 2
    try:
        out = open(args.output, "w", newline="", encoding="utf-8") if args.output else sys.stdout
        try:
            if args.csv:
                n = hist.export_csv(out, since, until)
                if args.output:
                    print(f"{n} rows written to {args.output}", file=sys.stderr)
                return 0
            _summary(hist, since, until, out)
        finally:
            if args.output:
                out.close()
    finally:
        hist.close()
    return 0


def _summary(hist: AngleHistory, since, until, out) -> None:
    from posed.daemon.history.store import ANGLE_COLUMNS

    rows = list(hist.rows(since, until))
    if not rows:
        print("no joint angles stored for that time range", file=out)
        return
    print(f"{len(rows)} frames from {iso(rows[0][0])} to {iso(rows[-1][0])} (UTC); --csv exports them", file=out)
    print(f"{'angle':<12} {'min':>8} {'mean':>8} {'max':>8}", file=out)
    for i, name in enumerate(ANGLE_COLUMNS):
        vals = [r[4 + i] for r in rows if r[4 + i] is not None and math.isfinite(r[4 + i])]
        if vals:
            print(f"{name:<12} {min(vals):8.1f} {sum(vals) / len(vals):8.1f} {max(vals):8.1f}", file=out)
