"""The daily report and the pauses for privacy (daemon.history.paused), through ``posed report`` on a real history
file (SQLite, written by the product's own WatchLog and PauseLog as the daemon writes them): posed watching an
empty room a frame a second, off at night, and paused twice (no frame while paused).

* the day's pauses are listed and summed in the robot's zone ("Watching paused for privacy: 1 h 05 min — 14:02–14:47,
  asked by voice, resumed by time; ...") and counted apart: the table's "paused for privacy" row, "not watching"
  only the hours posed was off, and the rows still make the whole day;
* a minute of the day grid is "paused for privacy" exactly where a pause took it;
* a pause still running when the report is made, and one across midnight, are said and counted to now / to
  the day's end;
* a day without a pause reads as before: nothing about pausing anywhere (also from a history without the table)."""

from __future__ import annotations

import datetime as dt
import re
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from posed.cli import main
from posed.daemon.history.paused import PauseLog
from posed.daemon.history.store import AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.viz import posture
from posed.viz.report import PAUSED, _hm, day_pauses, day_report, minute_states
from posed.viz.series import AngleSeries

TZ = ZoneInfo("Europe/Berlin")      # not this machine's zone (UTC): the report must follow --tz
DAY = dt.date(2026, 12, 6)
ON = ("07:00", "22:00")             # posed running (local time); off the rest of the day
# (from, to, asked by, how it ended, resumed by)
PAUSES = (("14:02", "14:47", "voice", "time", None), ("20:10", "20:30", "app", "resumed", "Anna"))


def at(hhmm: str, day: dt.date = DAY) -> float:
    return dt.datetime.combine(day, dt.time.fromisoformat(hhmm), TZ).timestamp()


def write_day(path, pauses=PAUSES) -> None:
    """The history file: the angles table (empty: nobody in view), a frame a second while posed runs and is not
    paused, and the pauses as the daemon's keeper records them (begin, then end)."""
    AngleHistory(path).close()
    held = [(at(a), at(b)) for a, b, *_ in pauses]
    with WatchLog(path) as w:
        for t in np.arange(at(ON[0]), at(ON[1]), 1.0):
            if not any(a <= t < b for a, b in held):
                w.add(float(t), person=False, fitted=False)
    with PauseLog(path, clock=lambda: at("23:59")) as log:
        for a, b, by, ended, resumed_by in pauses:
            log.begin(at(a), at(b) if ended == "time" else at(b) + 600.0, by)
            log.end(at(b), ended, resumed_by)


def report(tmp_path, path, name="r.html") -> str:
    out = tmp_path / name
    assert main(["report", "--day", DAY.isoformat(), "--db", str(path), "--tz", "Europe/Berlin",
                 "-o", str(out)]) == 0
    return out.read_text()


def rows_of(text: str) -> dict[str, str]:
    return dict(re.findall(r"<tr><td(?: class='warn')?>([^<]+)</td><td>([^<]+)</td><td>", text))


def test_the_days_pauses_are_listed_summed_and_counted_apart(tmp_path):
    path = tmp_path / "history.sqlite3"
    write_day(path)
    text = report(tmp_path, path)
    paused_s = sum(at(b) - at(a) for a, b, *_ in PAUSES)
    on_s = at(ON[1]) - at(ON[0])
    items = "; ".join(f"{a}–{b}, asked by {by}, resumed by {rb or 'time'}" for a, b, by, _, rb in PAUSES)
    assert f"Watching paused for privacy: <b>{_hm(paused_s)}</b> — {items}." in text
    rows = rows_of(text)
    assert rows[PAUSED] == _hm(paused_s)
    assert rows["not watching (posed off or no camera)"] == _hm(86400.0 - on_s)     # the night, not the pauses
    assert rows["watching, nobody in view"] == _hm(on_s - paused_s)
    assert f"paused for privacy for <b>{_hm(paused_s)}</b>" in text
    assert f"not watching for {_hm(86400.0 - on_s)}</b>" in text
    assert f"it was paused for privacy for {_hm(paused_s)} and not watching for {_hm(86400.0 - on_s)}" in text


def test_the_day_grid_marks_the_paused_minutes(tmp_path):
    path = tmp_path / "history.sqlite3"
    write_day(path)
    span = (at("00:00"), at("00:00", DAY + dt.timedelta(days=1)))
    with WatchLog(path, readonly=True) as w, PauseLog(path, readonly=True) as p:
        watched, spans = w.minutes(*span), p.between(*span)
    summary = posture.summarise(np.zeros(0), {}, span, 1.0)
    states = minute_states(summary, watched, span, span[1], day_pauses(spans, span, span[1]))
    expected = {i for a, b, *_ in PAUSES for i in range(int((at(a) - span[0]) // 60), int((at(b) - span[0]) // 60))}
    assert {i for i, s in enumerate(states) if s == PAUSED} == expected


def test_a_pause_running_now_and_one_across_midnight(tmp_path):
    """Made at 15:00 during a pause begun at 14:50 (due 15:30): counted up to now, said still running. A pause
    from 23:40 to 00:20 counts 20 min on each day, its end named with the next day's date."""
    path = tmp_path / "history.sqlite3"
    now = at("15:00")
    write_day(path, pauses=())
    with PauseLog(path, clock=lambda: now) as log:
        log.begin(at("14:50"), at("15:30"), "voice")
    with WatchLog(path, readonly=True) as w, PauseLog(path, readonly=True) as p:
        span = (at("00:00"), at("00:00", DAY + dt.timedelta(days=1)))
        watched, spans = w.minutes(*span), p.between(*span)
    empty = AngleSeries(np.zeros(0), {}, True)
    text = day_report(empty, [], DAY, TZ, robot="r", sources="s", watched=watched, paused=spans, now=now)
    assert ("Watching paused for privacy: <b>10 min</b> — 14:50–now, asked by voice, still paused when this "
            "report was made (until 15:30).") in text
    assert rows_of(text)[PAUSED] == "10 min"

    later = tmp_path / "later.sqlite3"
    write_day(later, pauses=())
    nxt = DAY + dt.timedelta(days=1)
    with PauseLog(later) as log:
        log.begin(at("23:40"), at("00:20", nxt), None)
        log.end(at("00:20", nxt), "time")
    with PauseLog(later, readonly=True) as p:
        spans = p.between(at("00:00"), at("00:00", nxt))
    text = day_report(empty, [], DAY, TZ, robot="r", sources="s", watched=[], paused=spans, now=at("12:00", nxt))
    assert (f"<b>20 min</b> — 23:40–00:20 ({nxt.isoformat()}), who asked was not said, resumed by time."
            in text) and rows_of(text)[PAUSED] == "20 min"


@pytest.mark.parametrize("table", [True, False])
def test_a_day_without_a_pause_shows_nothing_new(tmp_path, table):
    path = tmp_path / "history.sqlite3"
    write_day(path, pauses=())
    if table:                      # a posed that can pause (the table there, empty) or an older one (none)
        PauseLog(path).close()
    text = report(tmp_path, path)
    # what a reader sees (the style is the same; the file's path is this test's name)
    shown = re.sub(r"<style>.*?</style>", "", text, flags=re.S).replace(str(tmp_path), "")
    assert not re.search("paus", shown, re.I), re.findall(r".{60}paus.{60}", shown, re.I)
    rows = rows_of(text)
    assert rows["not watching (posed off or no camera)"] == _hm(86400.0 - (at(ON[1]) - at(ON[0])))
