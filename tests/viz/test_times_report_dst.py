"""The daily report and the history plot on the days the clocks change, and with times stamped later than now.

* The day the clocks go back is 25 hours, the day they go forward 23 (Europe/London and America/New_York, real
  zoneinfo, the zone from $TZ in the command's environment): the report says so and counts the hours watched
  in unix time; a fall in the hour that happens twice is shown with its zone and offset (``01:30:00 BST
  (UTC+01:00)``, ``01:30:00 GMT (UTC+00:00)``), as ``posed events`` prints it; the day grid names both 01:00
  hours; the plot's clock axis has ticks across the whole night (both 01:00) and its label says when the clocks
  changed.
* A robot whose clock was wrong and set right (NTP at boot): samples and falls stamped later than the report
  is made are said to be so, never counted as time passed, never "in progress"; falls of a later day so
  stamped are named.

Real history (``AngleHistory``, ``WatchLog``) and journal (``EventJournal``) files, the real ``posed report``
and ``posed plot history`` as processes, the real figure function for the ticks."""

from __future__ import annotations

import datetime as dt
import html
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from zoneinfo import ZoneInfo

import pytest

from posed.daemon.history.store import AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.daemon.outbox.journal import EventJournal
from posed.falls.config import FallsConfig
from posed.falls.event import FallEvent
from posed.fitting import JOINT_ANGLE_NAMES, FitResult

ROOT = Path(__file__).resolve().parents[2]
# (zone, the day the clocks go back, the UTC hour of the first 01:30, its abbreviations and offsets)
BACK = [("Europe/London", dt.date(2026, 10, 25), 0, ("BST (UTC+01:00)", "GMT (UTC+00:00)")),
        ("America/New_York", dt.date(2026, 11, 1), 5, ("EDT (UTC-04:00)", "EST (UTC-05:00)"))]
FORWARD = [("Europe/London", dt.date(2026, 3, 29)), ("America/New_York", dt.date(2026, 3, 8))]


def posed(*args: str, tz: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "TZ": tz, "POSED_CONFIG": ""}
    return subprocess.run([sys.executable, "-m", "posed", *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)


def record(folder: Path, sessions, falls) -> None:
    """A person standing, one frame a second, in each (start, seconds) of ``sessions`` (angles into the
    history, frames into the minutes watched), and a ``falling`` message at each (id, unix time) of ``falls``."""
    folder.mkdir(parents=True, exist_ok=True)
    with AngleHistory(folder / "history.sqlite3", FallsConfig(history_rate_hz=1.0)) as hist, \
            WatchLog(folder / "history.sqlite3") as watched:
        for start, seconds in sessions:
            for i in range(int(seconds)):
                hist.add(FitResult(seq=i, t=float(i), ok=True, joint_angles_deg=dict.fromkeys(JOINT_ANGLE_NAMES, 0.0),
                                   variables={"theta_bd": 0.0, "phi_bd": 0.0, "psi_bd": 0.0}), wall=start + i)
                watched.add(start + i, person=True, fitted=True)
    for id_, wall in falls:
        with EventJournal(folder / "events.sqlite3", clock=lambda w=wall: w) as journal:
            journal.append(FallEvent(id=id_, robot="r", state="falling", t_onset=1.0, t_impact=1.5, t_detect=2.0,
                                     confidence=0.9))


def report_text(folder: Path, day: str, tz: str) -> str:
    out = folder / "report.html"
    done = posed("report", "--day", day, "--db", str(folder / "history.sqlite3"), "-o", str(out), tz=tz)
    assert done.returncode == 0, done.stderr
    text = re.sub(r"<img[^>]*>", "[picture]", out.read_text())
    return html.unescape(re.sub(r"<[^>]+>", " ", text[text.index("<body>"):]))


def fall_rows(text: str) -> list[str]:
    return [" ".join(line.split()) for line in text.splitlines() if re.match(r"\s*fall \d", line)]


@pytest.mark.parametrize(("zone", "day", "utc_hour", "marks"), BACK)
def test_the_day_the_clocks_go_back_has_25_hours_and_tells_the_two_0130_apart(tmp_path, zone, day, utc_hour,
                                                                               marks):
    first = dt.datetime.combine(day, dt.time(utc_hour, 30), dt.UTC).timestamp()     # 01:30, summer time
    second = first + 3600.0                                                           # 01:30 again
    record(tmp_path, [(first - 60, 180), (second - 60, 180)], [("a" * 32, first), ("b" * 32, second)])
    text = report_text(tmp_path, day.isoformat(), zone)
    assert "this day has 25 hours" in text
    assert "from 02:00 the clocks went back to 01:00" in text
    assert "of 25 h 00 min" in text                      # the hours watched out of the day's, in unix time
    rows = fall_rows(text)
    assert rows[0].startswith(f"fall 1 01:30:00 {marks[0]} fall")
    assert rows[1].startswith(f"fall 2 01:30:00 {marks[1]} fall")
    # posed events prints the same two moments with the same offsets
    listed = posed("events", "--journal", str(tmp_path / "events.sqlite3"), tz=zone).stdout.splitlines()
    offsets = [m.split("(UTC")[1].rstrip(")") for m in marks]
    assert listed[1].startswith(f"{day.isoformat()}T01:30:00{offsets[0]}")
    assert listed[2].startswith(f"{day.isoformat()}T01:30:00{offsets[1]}")


@pytest.mark.parametrize(("zone", "day"), FORWARD)
def test_the_day_the_clocks_go_forward_has_23_hours(tmp_path, zone, day):
    tz = ZoneInfo(zone)
    midnight = dt.datetime.combine(day, dt.time(0), tz).timestamp()
    # watched from 00:30 to 04:30 by the clock, which is 3 hours (an hour is skipped); a fall at 03:30
    start = dt.datetime.combine(day, dt.time(0, 30), tz).timestamp()
    end = dt.datetime.combine(day, dt.time(4, 30), tz).timestamp()
    assert end - start == 3 * 3600
    record(tmp_path, [(start, end - start)], [("c" * 32, dt.datetime.combine(day, dt.time(3, 30), tz).timestamp())])
    text = report_text(tmp_path, day.isoformat(), zone)
    assert "this day has 23 hours" in text
    assert "the clocks went forward" in text
    assert "posed was watching for 3 h 00 min of 23 h 00 min" in " ".join(text.split())
    assert fall_rows(text)[0].startswith("fall 1 03:30:00 fall")      # not ambiguous: no offset needed
    assert midnight < start


def test_the_day_grid_and_the_plot_name_both_0100_hours(tmp_path):
    from posed.commands._history_series import angle_series, event_marks
    from posed.daemon.history.store import ANGLE_COLUMNS
    from posed.viz.names import PANELS
    from posed.viz.plots import angle_figure
    from posed.viz.report import day_grid_figure
    from posed.viz.series import episodes

    tz = ZoneInfo("Europe/London")
    first = dt.datetime(2026, 10, 25, 0, 30, tzinfo=dt.UTC).timestamp()
    record(tmp_path, [(first - 60, 180), (first + 3600 - 60, 180)], [("a" * 32, first), ("b" * 32, first + 3600)])
    with AngleHistory(tmp_path / "history.sqlite3", readonly=True) as hist:
        series = angle_series(list(hist.rows()), ANGLE_COLUMNS)
    with EventJournal(tmp_path / "events.sqlite3", readonly=True) as journal:
        falls = episodes(event_marks(journal.query()))
    fig = angle_figure(series, [("legs", PANELS["legs"])], falls, title="t", tz=tz)
    fig.canvas.draw()
    ax = fig.axes[-1]
    labels = [t.get_text() for t in ax.get_xticklabels()]
    ticks = ax.get_xticks() * 86400.0
    lo, hi = (v * 86400.0 for v in ax.get_xlim())
    assert any(x.startswith("01:00 GMT") for x in labels), labels        # the second 01:00 is a tick
    assert any(x.startswith("01:30 BST") for x in labels) and any(x.startswith("01:30 GMT") for x in labels)
    assert len(ticks) >= 4 and ticks[0] - lo < 0.2 * (hi - lo) and hi - ticks[-1] < 0.2 * (hi - lo)
    assert "from 02:00 the clocks went back to 01:00 (UTC+00:00)" in ax.get_xlabel()
    notes = [t.get_text() for t in fig.texts]
    assert any("fall 1: 01:30:00 BST (UTC+01:00)" in n for n in notes)
    assert any("fall 2: 01:30:00 GMT (UTC+00:00)" in n for n in notes)
    start = dt.datetime.combine(dt.date(2026, 10, 25), dt.time(0), tz).timestamp()
    end = dt.datetime.combine(dt.date(2026, 10, 26), dt.time(0), tz).timestamp()
    grid = day_grid_figure(["not yet"] * int((end - start) // 60), falls, (start, end), tz)
    hours = [t.get_text() for t in grid.axes[0].get_yticklabels()]
    assert len(hours) == 25 and hours[:4] == ["00:00", "01:00 BST", "01:00 GMT", "02:00"]
    done = posed("plot", "history", "--db", str(tmp_path / "history.sqlite3"), "--since", "2026-10-25",
                 "-o", str(tmp_path / "night.png"), tz="Europe/London")
    assert done.returncode == 0, done.stderr


def test_times_stamped_later_than_the_report_are_said_and_never_counted(tmp_path):
    """The robot's clock ran ahead when these were stored, and was set right before the report was made."""
    zone = "Europe/London"
    now = time.time()
    ahead = now + 120.0
    day = dt.datetime.fromtimestamp(ahead, ZoneInfo(zone)).date().isoformat()
    record(tmp_path, [(ahead, 60)], [("d" * 32, ahead + 30), ("e" * 32, now + 3 * 86400)])
    page = report_text(tmp_path, day, zone)
    text = " ".join(page.split())
    assert "Times later than now:" in text
    assert "60 sample(s) of this day (not counted below)" in text
    assert "1 of this day's fall event(s) (listed below)" in text
    assert "1 fall event(s) of a later day" in text
    (row,) = fall_rows(page)
    assert "stamped later than this report was made" in row and "in progress" not in row
    assert "standing 0 s" in text                     # a minute stamped ahead is not time that has passed
