"""The daily report, on a real history and journal made by replaying a real fall (urfd_04) through the fit and
the fall detector as tests/viz/day.py does:

* a fall whose last message is seconds old when the report is made (posed still watching, neither got up nor
  the alarm yet) is "in progress when this report was made (HH:MM:SS)", never "the person left the view";
  the same fall an hour later is no longer in progress;
* a finished day posed never watched says "not measured" for sit-to-stand and walking, "no samples" in the
  angle table and "share of the day" (not "so far");
* a fall's states in the report are the web page's words (the hub sends the page the same table)."""

from __future__ import annotations

import datetime as dt
import re
from zoneinfo import ZoneInfo

import numpy as np
import pytest

from posed.commands._history_series import angle_series, event_marks
from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.history.store import ANGLE_COLUMNS, AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.daemon.outbox.journal import EventJournal
from posed.falls import FallsConfig
from posed.landmarks import read_recording
from posed.viz.report import day_report
from posed.viz.series import AngleSeries, episodes
from posed.viz.web.hub import Hub
from tests.viz.day import GEOMETRY

TZ = ZoneInfo("Europe/Berlin")
DAY = dt.date(2026, 12, 6)


@pytest.fixture(scope="module")
def fall_so_far(tmp_path_factory, shared_data):
    """urfd_04 replayed from 22:31:00 into a history and a journal, stopped right after its first fall
    message, as a report made while posed is still watching finds them."""
    folder = tmp_path_factory.mktemp("inprogress")
    cfg = load_config(None, overrides=GEOMETRY)
    start = dt.datetime.combine(DAY, dt.time(22, 31), TZ).timestamp()
    header, frames, _ = read_recording(shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl")
    clock = {"now": start}
    first = None
    with AngleHistory(folder / "history.sqlite3", cfg.falls) as hist, WatchLog(folder / "history.sqlite3") as w, \
            EventJournal(folder / "events.sqlite3", clock=lambda: clock["now"]) as journal:
        for frame, result, messages in detect(cfg, header, fit_frames(cfg, header, frames)):
            clock["now"] = start + frame.t
            hist.add(result, wall=clock["now"])
            w.add(clock["now"], person=result.ok or result.reason != "no person", fitted=result.ok)
            for ev in messages:
                journal.append(ev)
                first = first or (ev.state, clock["now"])
            if first is not None:
                break
    assert first is not None, "the detector found no fall in urfd_04 (did it change?)"
    with AngleHistory(folder / "history.sqlite3", readonly=True) as h:
        rows = list(h.rows())
    with WatchLog(folder / "history.sqlite3", readonly=True) as w:
        watched = w.minutes(0, 4e9)
    with EventJournal(folder / "events.sqlite3", readonly=True) as j:
        falls = episodes(event_marks(j.query()))
    assert len(falls) == 1 and falls[0].states == (first[0],)
    return angle_series(rows, ANGLE_COLUMNS), falls, watched, first[1]


def _fall_row(text: str) -> list[str]:
    row = re.search(r"<tr><td>fall 1</td>(.*?)</tr>", text)
    assert row, text
    return re.findall(r"<td[^>]*>(.*?)</td>", row.group(1))


def test_a_fall_seconds_old_is_in_progress_not_left_the_view(fall_so_far):
    series, falls, watched, last = fall_so_far
    now = last + 2.0                       # the report made two seconds after the fall's message
    text = day_report(series, falls, DAY, TZ, robot="r", sources="s", watched=watched, now=now)
    when = dt.datetime.fromtimestamp(now, TZ).strftime("%H:%M:%S")
    started, what, ended, acked = _fall_row(text)
    assert ended == f"in progress when this report was made ({when})", ended
    assert "left the view" not in text
    # still in progress just inside the detector's alarm time plus the margin, no longer after it
    window = FallsConfig().alarm_after_s
    inside = day_report(series, falls, DAY, TZ, robot="r", sources="s", watched=watched, now=last + window)
    assert "in progress when this report was made" in _fall_row(inside)[2]
    later = day_report(series, falls, DAY, TZ, robot="r", sources="s", watched=watched, now=last + 3600.0)
    ended_later = _fall_row(later)[2]
    assert "in progress" not in ended_later
    assert ended_later in ("no further message (the person left the view)", "on the floor; no recovery seen")


def test_the_report_words_a_fall_s_states_as_the_web_page(fall_so_far):
    series, falls, watched, last = fall_so_far
    words = Hub("r").snapshot()["state_words"]             # what the page joins with " → "
    assert words == {"falling": "fall", "on_floor": "on the floor", "alarm": "ALARM", "recovered": "got up"}
    text = day_report(series, falls, DAY, TZ, robot="r", sources="s", watched=watched, now=last + 2.0)
    assert _fall_row(text)[1] == " → ".join(words[s] for s in falls[0].states)
    from posed.viz.series import Episode

    full = Episode("x", last, last + 20, ("falling", "on_floor", "recovered"))
    text = day_report(series, [full], DAY, TZ, robot="r", sources="s", watched=watched, now=last + 3600)
    _, what, ended, _ = _fall_row(text)
    assert what == "fall → on the floor → got up" and ended == "got up"
    assert "falling" not in what and "recovered" not in text.split("<h2>Falls</h2>")[1].split("</table>")[0]


def test_a_finished_day_posed_never_watched_measures_nothing(tmp_path):
    with WatchLog(tmp_path / "history.sqlite3") as w:      # a real history with nothing in it that day
        pass
    with WatchLog(tmp_path / "history.sqlite3", readonly=True) as w:
        start = dt.datetime.combine(DAY - dt.timedelta(days=1), dt.time(0), TZ).timestamp()
        watched = w.minutes(start, start + 86400)
    assert watched == []
    empty = AngleSeries(np.zeros(0), {}, True)
    text = day_report(empty, [], DAY - dt.timedelta(days=1), TZ, robot="r", sources="s", watched=watched,
                      now=dt.datetime.combine(DAY, dt.time(22, 31), TZ).timestamp())
    assert "posed was not watching at all this day" in text
    assert "<tr><td>sit-to-stand transitions</td><td>0</td>" not in text and "walking bouts</td><td>0" not in text
    activity = text.split("<h2>Activity</h2>")[1].split("</table>")[0]
    assert activity.count("not measured (posed was not watching)") == 2, activity
    ranges = text.split("<h2>Joint-angle ranges</h2>")[1].split("</table>")[0]
    assert "no samples" in ranges
    assert "<th>share of the day</th>" in text and "so far" not in text
    # a day not over keeps "so far"
    today = day_report(empty, [], DAY, TZ, robot="r", sources="s", watched=watched,
                       now=dt.datetime.combine(DAY, dt.time(12, 0), TZ).timestamp())
    assert "<th>share of the day so far</th>" in today
