"""``posed history [--since T] [--until T] [--tz ZONE | --utc] [--csv] [-o FILE]``: export the stored joint
angles. The summary's times are in the robot's zone (as ``posed report`` and ``posed plot history`` show them:
``--tz`` another, ``--utc`` UTC as before), each with its UTC offset; the CSV is unchanged (``wall_time`` ISO
UTC, ``wall`` unix seconds).

Exit status: 0 written, 2 a bad time or range, a missing history file, or an output that is the history file
(or the config file) or cannot be created, 74 writing failed (a full disk: a partial output file is removed).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING
from zoneinfo import ZoneInfo

from posed.commands import add_config_args, config_from_args, config_path
from posed.commands._paths import Output, OutputError, config_inputs, refuse_same_file
from posed.daemon.config.paths import HISTORY_FILE, reading_state_dir
from posed.daemon.timeparse import clock_text, future_note, iso, local_zone, parse_time, zone_name

if TYPE_CHECKING:
    from posed.daemon.config.sections import PipelineConfig
    from posed.daemon.history.store import AngleHistory


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("history", help="export or summarise the stored joint-angle history")
    add_config_args(parser, source=False, example="pipeline.state_dir=/var/lib/posed")
    add_range_args(parser)
    add_zone_args(parser)
    parser.add_argument("--csv", action="store_true", help="write CSV (one row per kept frame)")
    parser.add_argument("-o", "--output", metavar="FILE", help="write to FILE instead of stdout")
    parser.set_defaults(func=run)


def add_range_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--since", metavar="TIME", help="from this time: 2h, 7d, today, 2024-05-01T14:00, ...")
    parser.add_argument("--until", metavar="TIME", help="up to this time (same forms as --since)")
    parser.add_argument("--db", metavar="FILE", help="history file (default: history.sqlite3 in the state dir)")


def add_zone_args(parser: argparse.ArgumentParser) -> None:
    """``--tz`` and ``--utc``: the zone the listing's times are printed in (default the robot's, as the report
    and the plots show them)."""
    zone = parser.add_mutually_exclusive_group()
    zone.add_argument("--tz", metavar="ZONE",
                      help="print times in this time zone, and read a --since/--until without an offset in it "
                           "(IANA name, e.g. Europe/Berlin; default: this machine's, the robot's, as posed report "
                           "and posed plot history use)")
    zone.add_argument("--utc", action="store_true",
                      help="print times in UTC, as earlier versions did (a --since/--until without an offset is "
                           "then UTC too)")


def display_zone(args: argparse.Namespace):
    """The zone ``--tz``/``--utc`` name (UTC for ``--utc``), else the robot's (``timeparse.local_zone``);
    ValueError for an unknown name."""
    if getattr(args, "utc", False):
        return ZoneInfo("UTC")
    return local_zone(getattr(args, "tz", None))


def open_history(args: argparse.Namespace, pipeline: PipelineConfig | None = None, tz=None
                 ) -> tuple[AngleHistory, float | None, float | None]:
    """Parse --since/--until/--db and open the history read-only (raises ValueError/FileNotFoundError).

    ``pipeline``: the config's pipeline section when the caller has loaded it (else it is loaded here when
    there is no --db); ``tz``: the zone of a --since/--until without an offset (default: this machine's)."""
    from posed.daemon.history.store import AngleHistory  # not at import: it pulls in structlog

    since, until = time_range(args, tz)
    if args.db:
        path = Path(args.db)
    else:
        path = history_path(pipeline if pipeline is not None else config_from_args(args).pipeline,
                            config_path(args))
    return AngleHistory(path, readonly=True), since, until


def time_range(args: argparse.Namespace, tz=None) -> tuple[float | None, float | None]:
    """``--since`` and ``--until`` as Unix times (None: open), a date or time without an offset in ``tz``
    (default: this machine's zone); ValueError for a time that cannot be read or a --since after the --until."""
    since = parse_time(args.since, tz=tz) if args.since else None
    until = parse_time(args.until, tz=tz) if args.until else None
    if since is not None and until is not None and since > until:
        shown = (lambda t: clock_text(t, tz)) if tz is not None else iso
        raise ValueError(f"--since {args.since} ({shown(since)}) is after --until {args.until} ({shown(until)}): "
                         "give the earlier time to --since")
    return since, until


def history_path(pipeline: PipelineConfig, config_file: Path | None) -> Path:
    """history.sqlite3 in the state dir a reading command opens (the service's when it is the one in use)."""
    return reading_state_dir(pipeline, config_file, HISTORY_FILE) / HISTORY_FILE


def where_from(args: argparse.Namespace, pipeline: PipelineConfig | None = None) -> str:
    """Which history file a reading command opens, and why that one (said on stderr, so a reader of another
    daemon's state dir knows to point elsewhere)."""
    if args.db:
        return f"{args.db} (--db)"
    if pipeline is None:
        pipeline = config_from_args(args).pipeline
    path = history_path(pipeline, config_path(args))
    if pipeline.state_dir:
        why = "pipeline.state_dir"
    elif str(path.parent) == "/var/lib/posed":
        why = "the service's state dir"
    else:
        why = "this user's default state dir"
    return f"{path} ({why}; another daemon's history: --db FILE or --set pipeline.state_dir=DIR)"


def run(args: argparse.Namespace) -> int:
    cmd = "posed history"
    try:
        pipeline = None if args.db else config_from_args(args).pipeline
        print(f"{cmd}: reading {where_from(args, pipeline)}", file=sys.stderr)
        db = Path(args.db) if args.db else history_path(pipeline, config_path(args))
        refused = refuse_same_file(cmd, args.output, [("history database", db), *config_inputs(args)])
        if refused is not None:
            return refused
        tz = display_zone(args)
        hist, since, until = open_history(args, pipeline, tz)
    except (ValueError, FileNotFoundError) as exc:
        print(f"{cmd}: {exc}", file=sys.stderr)
        return 2
    out = Output(cmd, args.output, newline="")
    try:
        out.open()
    except OSError as exc:
        hist.close()
        return out.open_failed(exc)
    try:
        if args.csv:
            n = hist.export_csv(out, since, until)
            out.close()
            if args.output:
                print(f"{n} rows written to {args.output}", file=sys.stderr)
            return 0
        _summary(hist, since, until, out, None if args.utc else tz)
        out.close()
    except OutputError as exc:
        return out.failed(exc.exc)
    except ValueError as exc:       # HistoryFileError: damage found while reading the rows
        print(f"posed history: {exc}", file=sys.stderr)
        return 2
    finally:
        out.discard()
        hist.close()
    return 0


def span_line(first: float, last: float, tz) -> str:
    """``from 2026-10-25 01:29:00+01:00 to 2026-10-25 01:31:59+00:00 (Europe/London)`` (``tz`` None: UTC, as
    posed printed it before), and what to know of a last time later than now (a clock set right since)."""
    if tz is None:
        text = f"from {iso(first)} to {iso(last)} (UTC)"
    else:
        text = f"from {clock_text(first, tz)} to {clock_text(last, tz)} ({zone_name(tz, first)})"
    note = future_note(last)
    return text + (f"; the last is {note}" if note else "")


def _summary(hist: AngleHistory, since, until, out, tz=None) -> None:
    from posed.daemon.history.store import ANGLE_COLUMNS
    from posed.fitting import ANGLE_PLAIN_NAMES, FIXED_ANGLE_NAMES

    rows = list(hist.rows(since, until))
    if not rows:
        print("no joint angles stored for that time range", file=out)
        return
    print(f"{len(rows)} frames {span_line(rows[0][0], rows[-1][0], tz)}; --csv exports them (columns by "
          "the model's symbols, docs/body-model.md)", file=out)
    print("degrees, over the frames in which the camera saw the joint (samples)", file=out)
    print(f"{'angle':<26} {'samples':>7} {'min':>8} {'mean':>8} {'max':>8}", file=out)
    unseen = []
    for i, name in enumerate(ANGLE_COLUMNS):
        if name in FIXED_ANGLE_NAMES:      # held fixed by the model: never a measurement
            continue
        vals = [r[4 + i] for r in rows if r[4 + i] is not None and math.isfinite(r[4 + i])]
        plain = ANGLE_PLAIN_NAMES.get(name, name)
        if vals:
            print(f"{plain:<26} {len(vals):>7} {min(vals):8.1f} {sum(vals) / len(vals):8.1f} {max(vals):8.1f}",
                  file=out)
        else:
            unseen.append(plain)
    if unseen:
        print("not seen in this time range: " + ", ".join(unseen), file=out)
