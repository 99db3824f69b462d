"""The report and the history plot's fall notes on a real journal of a real fall (urfd_04 replayed through the
fit and the fall detector into an EventJournal, as tests/viz/day.py does), then the daemon's later messages:

* a fall whose first messages were acknowledged and whose ALARM came after is NOT "acknowledged": the
  report says the ALARM is not, and who acknowledged the rest (it said "acknowledged HH:MM:SS", the time of
  the earliest acknowledgement, for a fall whose alarm nobody had seen);
* who acknowledged (the journal's ``acked_by``) is shown beside the time;
* an alarm raised after a restart (``restored``) and without camera frames (``without_frames_s``) says so."""

from __future__ import annotations

import dataclasses
import datetime as dt
import re
from zoneinfo import ZoneInfo

import pytest

from posed.commands._history_series import event_marks
from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.outbox.journal import EventJournal
from posed.landmarks import read_recording
from posed.viz.report import day_report
from posed.viz.series import AngleSeries, episodes
from tests.viz.day import GEOMETRY

TZ = ZoneInfo("Europe/Berlin")
DAY = dt.date(2026, 12, 6)


@pytest.fixture(scope="module")
def journal(tmp_path_factory, shared_data):
    folder = tmp_path_factory.mktemp("acks")
    cfg = load_config(None, overrides=GEOMETRY)
    start = dt.datetime.combine(DAY, dt.time(22, 31), TZ).timestamp()
    header, frames, _ = read_recording(shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl")
    clock = {"now": start}
    path = folder / "events.sqlite3"
    with EventJournal(path, clock=lambda: clock["now"]) as j:
        last = None
        for frame, _result, messages in detect(cfg, header, fit_frames(cfg, header, frames)):
            clock["now"] = start + frame.t
            for ev in messages:
                last = j.append(ev)
        assert last is not None and last.state == "on_floor", "urfd_04 gives no on_floor any more"
        clock["now"] += 5
        j.acknowledge(last.id, None, by="anna (daughter)")       # what was seen so far
        # the daemon restarted, took the fall back and raised its alarm while no frame came
        clock["now"] += 40
        alarm = dataclasses.replace(last, state="alarm", extra={
            **last.extra, "restored": {"at_unix": start + 20.0, "last_state": "on_floor", "due_unix": clock["now"]},
            "without_frames_s": 31.6})
        j.append(alarm)
    return path, start


def _fall_row(text: str) -> list[str]:
    row = re.search(r"<tr><td>fall 1</td>(.*?)</tr>", text, re.S)
    assert row, text
    return re.findall(r"<td[^>]*>(.*?)</td>", row.group(1), re.S)


def test_an_alarm_after_the_acknowledgement_is_not_acknowledged_and_who_is_named(journal):
    path, start = journal
    with EventJournal(path, readonly=True) as j:
        falls = episodes(event_marks(j.query()))
    assert len(falls) == 1 and falls[0].states == ("falling", "on_floor", "alarm")
    empty = AngleSeries(time=__import__("numpy").zeros(0), angles={}, clock=True)
    text = day_report(empty, falls, DAY, TZ, robot="r", sources="s", now=start + 3600)
    _, what, ended, acked = _fall_row(text)
    assert "ALARM: no" in acked, acked                           # never "acknowledged" while the alarm is not
    assert "anna (daughter)" in acked
    assert "posed restarted during this fall" in ended and "22:31:20" in ended, ended
    assert "no camera frame for 32 s" in ended
    line = falls[0].describe(lambda t: dt.datetime.fromtimestamp(t, TZ).strftime("%H:%M:%S"))
    assert "ALARM not acknowledged" in line and "by anna (daughter)" in line, line


def test_a_fall_acknowledged_in_full_says_when_and_by_whom(journal, tmp_path):
    path, start = journal
    import shutil
    copy = tmp_path / "events.sqlite3"
    shutil.copy(path, copy)
    with EventJournal(copy, clock=lambda: start + 100) as j:
        eid = j.query()[0].event.id
        j.acknowledge(eid, "alarm", by="night nurse")
    with EventJournal(copy, readonly=True) as j:
        falls = episodes(event_marks(j.query()))
    fmt = lambda t: dt.datetime.fromtimestamp(t, TZ).strftime("%H:%M:%S")   # noqa: E731
    assert falls[0].acked == start + 100
    assert falls[0].ack_text(fmt) == "acknowledged 22:32:40 by anna (daughter), night nurse"
