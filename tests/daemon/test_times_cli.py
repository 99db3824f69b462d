"""The times ``posed events`` and ``posed history`` print are in the zone the daily report and the history plot
use (the robot's: $TZ here, set in the command's environment, real zoneinfo), each with its UTC offset, so the
two 01:30 of the night the clocks go back read apart; ``--utc`` prints UTC as before, ``--json`` is unchanged;
a time stamped later than now (a clock set right since, e.g. by NTP at boot) is said to be so.

Real journal and history files written by the real classes, the real command as a process."""

from __future__ import annotations

import datetime as dt
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from posed.daemon.history.store import AngleHistory
from posed.daemon.outbox.journal import EventJournal
from posed.falls.config import FallsConfig
from posed.falls.event import FallEvent
from posed.fitting import JOINT_ANGLE_NAMES, FitResult

ROOT = Path(__file__).resolve().parents[2]
# Europe/London, 2026-10-25: at 02:00 BST the clocks go back to 01:00 GMT, so 01:30 happens twice
FIRST = dt.datetime(2026, 10, 25, 0, 30, tzinfo=dt.UTC).timestamp()     # 01:30 BST
SECOND = dt.datetime(2026, 10, 25, 1, 30, tzinfo=dt.UTC).timestamp()    # 01:30 GMT, an hour later


def posed(*args: str, tz: str = "Europe/London") -> subprocess.CompletedProcess:
    env = {**os.environ, "TZ": tz, "POSED_CONFIG": ""}
    return subprocess.run([sys.executable, "-m", "posed", *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=120)


def fall(id_: str, state: str = "falling") -> FallEvent:
    return FallEvent(id=id_, robot="r", state=state, t_onset=1.0, t_impact=1.5, t_detect=2.0, confidence=0.9)


def journal_at(path: Path, *messages: tuple[str, float]) -> None:
    for id_, wall in messages:
        with EventJournal(path, clock=lambda w=wall: w) as journal:
            journal.append(fall(id_))


def history_at(path: Path, walls) -> None:
    with AngleHistory(path, FallsConfig(history_rate_hz=1.0)) as hist:
        for i, wall in enumerate(walls):
            hist.add(FitResult(seq=i, t=float(i), ok=True, joint_angles_deg=dict.fromkeys(JOINT_ANGLE_NAMES, 5.0),
                               variables={"theta_bd": 0.0, "phi_bd": 0.0, "psi_bd": 0.0}), wall=wall)


def lines(text: str, needle: str) -> list[str]:
    return [line for line in text.splitlines() if needle in line]


def test_events_are_listed_in_the_robot_zone_with_their_offset(tmp_path):
    path = tmp_path / "events.sqlite3"
    journal_at(path, ("aaaa1111bbbb2222", FIRST), ("cccc3333dddd4444", SECOND))
    done = posed("events", "--journal", str(path))
    assert done.returncode == 0, done.stderr
    head, *rows = done.stdout.splitlines()
    assert head.startswith("time (Europe/London)")
    assert rows[0].startswith("2026-10-25T01:30:00+01:00  aaaa1111bbbb")    # BST
    assert rows[1].startswith("2026-10-25T01:30:00+00:00  cccc3333dddd")    # GMT, an hour later
    other = posed("events", "--journal", str(path), "--tz", "America/New_York")
    assert other.stdout.splitlines()[0].startswith("time (America/New_York)")
    assert other.stdout.splitlines()[1].startswith("2026-10-24T20:30:00-04:00")


def test_events_utc_prints_the_listing_as_before_and_json_is_unchanged(tmp_path):
    path = tmp_path / "events.sqlite3"
    journal_at(path, ("aaaa1111bbbb2222", FIRST), ("cccc3333dddd4444", SECOND))
    done = posed("events", "--journal", str(path), "--utc")
    assert done.returncode == 0, done.stderr
    head, *rows = done.stdout.splitlines()
    assert head.startswith("wall time (UTC)          event")
    assert rows[0].startswith("2026-10-25T00:30:00.000  aaaa1111bbbb")
    assert rows[1].startswith("2026-10-25T01:30:00.000  cccc3333dddd")
    # guard: the JSON keeps its times (ISO UTC text and unix seconds) whatever the zone
    listed = json.loads(posed("events", "--journal", str(path), "--json").stdout)
    assert [e["wall_time"] for e in listed["events"]] == ["2026-10-25T00:30:00.000+00:00",
                                                          "2026-10-25T01:30:00.000+00:00"]


def test_a_since_without_offset_is_read_in_the_zone_the_times_are_printed_in(tmp_path):
    path = tmp_path / "events.sqlite3"
    journal_at(path, ("aaaa1111bbbb2222", FIRST), ("cccc3333dddd4444", SECOND))
    # 2026-10-24T21:00 in New York (EDT) is 01:00 UTC on the 25th: only the second message is after it
    done = posed("events", "--journal", str(path), "--tz", "America/New_York", "--since", "2026-10-24T21:00")
    assert done.returncode == 0, done.stderr
    assert "cccc3333dddd" in done.stdout and "aaaa1111bbbb" not in done.stdout
    bad = posed("events", "--journal", str(path), "--tz", "Mars/Olympus")
    assert bad.returncode == 2 and "unknown time zone 'Mars/Olympus'" in bad.stderr


def test_history_summary_is_in_the_robot_zone_with_offsets(tmp_path):
    db = tmp_path / "history.sqlite3"
    history_at(db, [FIRST - 60 + i for i in range(120)] + [SECOND - 60 + i for i in range(120)])
    done = posed("history", "--db", str(db), "--since", "2026-10-25", "--until", "2026-10-26")
    assert done.returncode == 0, done.stderr
    assert ("240 frames from 2026-10-25T01:29:00+01:00 to 2026-10-25T01:30:59+00:00 (Europe/London);"
            in done.stdout)
    utc = posed("history", "--db", str(db), "--utc")
    assert "240 frames from 2026-10-25T00:29:00+00:00 to 2026-10-25T01:30:59+00:00 (UTC);" in utc.stdout
    # guard: the CSV keeps its columns (ISO UTC and unix seconds)
    csv = posed("history", "--db", str(db), "--csv").stdout.splitlines()
    assert csv[0].startswith("wall_time,wall,t,seq,level")
    assert csv[1].startswith(f"2026-10-25T00:29:00.000+00:00,{FIRST - 60!r},")


def test_times_stamped_later_than_now_are_said_to_be_so(tmp_path):
    """A robot whose clock ran 3 h ahead journalled a fall, then NTP set the clock right: the listing shows the
    time it was stamped with, and says it is later than now rather than leave it for the truth."""
    ahead = time.time() + 3 * 3600
    path = tmp_path / "events.sqlite3"
    journal_at(path, ("eeee5555ffff6666", ahead), ("0000777788889999", time.time() - 60))
    done = posed("events", "--journal", str(path))
    assert done.returncode == 0, done.stderr
    (future,) = lines(done.stdout, "eeee5555ffff")
    assert "stamped 3 h 00 min later than now by this machine's clock" in future or \
        "stamped 2 h 59 min later than now by this machine's clock" in future
    assert "the robot's clock was wrong when it was recorded" in future
    (past,) = lines(done.stdout, "000077778888")
    assert "later than now" not in past
    db = tmp_path / "history.sqlite3"
    history_at(db, [time.time() - 30, ahead])
    shown = posed("history", "--db", str(db)).stdout
    assert "; the last is stamped" in shown and "later than now by this machine's clock" in shown


def test_an_end_is_said_with_its_date_only_when_not_today_in_the_zone():
    from zoneinfo import ZoneInfo

    from posed.daemon.timeparse import until_text

    tokyo = ZoneInfo("Asia/Tokyo")
    now = dt.datetime(2026, 12, 7, 23, 40, tzinfo=tokyo).timestamp()
    assert until_text(now + 15 * 60, tokyo, now) == "23:55 JST"
    assert until_text(now + 40 * 60, tokyo, now) == "2026-12-08 00:20 JST"      # past midnight there
    assert until_text(now + 40 * 60, ZoneInfo("UTC"), now) == "15:20 UTC"       # the same instant, today in UTC
    assert until_text(now + 15 * 60, tokyo, now, zone=False) == "23:55"
