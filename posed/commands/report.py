"""``posed report --day YYYY-MM-DD [-o REPORT.html]``: the day's summary for a caregiver (viz.report).

Reads the joint-angle history, the minutes posed watched and the pauses for privacy (kept in the same file) and
the event journal (read-only, like ``posed plot history``) and writes one self-contained HTML file: whether posed
was watching (and when it was paused for privacy, counted apart), time standing, sitting, lying, in view and
with nobody in view, sit-to-stand transitions, walking bouts, falls and how they ended, the day's joint-angle
ranges, the day hour by hour and the angle plot. The day runs from local midnight to midnight in the robot's time
zone (``--tz`` another; ``daemon.timeparse.local_zone``, the zone ``posed events`` and ``posed history`` print
in): 23 or 25 hours the day the clocks go forward or back.
The part of today still to come is never counted, nor what was stamped later than now (a clock set right since).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from posed.commands import add_config_args, config_from_args, config_path, error_printer


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("report", help="a day's summary for a caregiver as one self-contained HTML file")
    parser.add_argument("--day", required=True, metavar="YYYY-MM-DD", help="the day (local time), or today, "
                                                                           "yesterday")
    parser.add_argument("-o", "--output", metavar="REPORT.html", help="file to write (default: "
                                                                      "posed-report-YYYY-MM-DD.html here)")
    parser.add_argument("--db", metavar="FILE", help="history file (default: history.sqlite3 in the state dir)")
    parser.add_argument("--journal", metavar="FILE", help="event journal (default: events.sqlite3 beside the "
                                                          "history)")
    parser.add_argument("--tz", metavar="ZONE", help="time zone (IANA name; default: this machine's)")
    add_config_args(parser, source=False, example="pipeline.state_dir=/var/lib/posed")
    parser.set_defaults(func=run)


_err = error_printer("posed report")


def _day(text: str, tz):
    import datetime as dt

    now = dt.datetime.now(tz).date()
    if text == "today":
        return now
    if text == "yesterday":
        return now - dt.timedelta(days=1)
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise ValueError(f"--day {text!r} is not a date; use YYYY-MM-DD (e.g. 2024-05-01), today or "
                         "yesterday") from None


def camera_down(config, state_dir: Path):
    """The camera's down the day's postures are measured against (viz.posture): the configured tilt and roll
    when ``falls.camera_geometry`` trusts them as measured, else the gravity the fall detector learned of
    this camera from people and kept in ``state_dir`` (its geometry file), as the fitting stage takes them
    (daemon.stages.fit: ``mount_gravity``, ``kept_gravity``); else None (the camera taken as level)."""
    from posed.daemon.stages.fall_watch import geometry_file
    from posed.daemon.stages.fit import kept_gravity, mount_gravity

    mount = mount_gravity(config.falls)
    return mount if mount is not None else kept_gravity(config.falls, geometry_file(state_dir, config.source))


def run(args: argparse.Namespace) -> int:
    import datetime as dt
    import time

    import numpy as np

    from posed.commands._history_series import angle_series, event_marks
    from posed.commands.history import history_path
    from posed.daemon.config.paths import EVENTS_FILE
    from posed.daemon.history.paused import PauseLog
    from posed.daemon.history.store import ROW_COLUMNS, AngleHistory, HistoryFileError
    from posed.daemon.history.watched import WatchLog
    from posed.daemon.outbox.journal import EventJournal, JournalError
    from posed.daemon.timeparse import local_zone
    from posed.viz.report import IN_PROGRESS_MARGIN_S, day_report
    from posed.viz.series import CLOCK_SLACK_S, episodes

    try:
        tz = local_zone(args.tz)
    except ValueError as exc:     # an unknown --tz, named with the fix
        _err(str(exc))
        return 2
    try:
        day = _day(args.day, tz)
    except ValueError as exc:
        _err(str(exc))
        return 2
    out = Path(args.output or f"posed-report-{day.isoformat()}.html")
    if out.suffix.lower() not in (".html", ".htm"):
        _err(f"{out} must end in .html (the report is one self-contained HTML file)")
        return 2
    config = config_from_args(args)
    db = Path(args.db) if args.db else history_path(config.pipeline, config_path(args))
    journal_path = Path(args.journal) if args.journal else db.with_name(EVENTS_FILE)
    start = dt.datetime.combine(day, dt.time(0), tz).timestamp()
    end = dt.datetime.combine(day + dt.timedelta(days=1), dt.time(0), tz).timestamp()
    try:
        with AngleHistory(db, readonly=True) as hist:
            rows = list(hist.rows(start, end, ROW_COLUMNS))
        with WatchLog(db, readonly=True) as watch_log:
            watched = watch_log.minutes(start, end)
        with PauseLog(db, readonly=True) as pause_log:
            paused = pause_log.between(start, end)
    except (FileNotFoundError, HistoryFileError) as exc:
        _err(str(exc))
        return 2
    series = angle_series(rows, ROW_COLUMNS)     # the angles and the down each sample was fitted against
    falls = []
    later = 0                                     # fall events of other days stamped later than now
    now = time.time()
    if journal_path.is_file():
        try:
            with EventJournal(journal_path, readonly=True) as journal:
                falls = episodes(event_marks(journal.query(start, end)))
                later = len({s.event.id for s in journal.query(max(end, now + CLOCK_SLACK_S))}
                            - {ep.id for ep in falls})
        except FileNotFoundError:   # gone, or being created by the daemon this moment: no fall yet
            falls, later = [], 0
        except JournalError as exc:
            _err(f"{exc}; the report needs the journal for the falls")
            return 1
    step = float(np.median(np.diff(series.time))) if len(series.time) > 1 else 1.0
    text = day_report(series, falls, day, tz, robot=config.robot_id, max_step_s=max(1.0, 3.0 * step),
                      watched=watched, paused=paused, down=camera_down(config, db.parent), now=now, stamped_later=later,
                      in_progress_s=config.falls.alarm_after_s + IN_PROGRESS_MARGIN_S,
                      sources=f"{db} ({len(rows)} samples) and "
                              + (f"{journal_path}" if journal_path.is_file() else "no event journal"))
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        _err(f"cannot write {out}: {exc.strerror or exc}")
        return 1
    _err(f"{out}: {len(rows)} samples, {len(falls)} fall(s)")
    return 0
