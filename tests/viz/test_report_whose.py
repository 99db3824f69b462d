"""The daily report says whose fall each was when the messages say it (several people in view: a household
member's name, "a visitor", or the track id), and nothing more with one person."""

from __future__ import annotations

import datetime as dt
from types import SimpleNamespace

from posed.commands._history_series import event_marks, whose
from posed.viz.report import day_report
from posed.viz.series import AngleSeries, episodes

TZ = dt.UTC
DAY = dt.date(2026, 5, 4)
T0 = dt.datetime.combine(DAY, dt.time(10), TZ).timestamp()


def stored(eid: str, state: str, wall: float, **extra):
    return SimpleNamespace(event=SimpleNamespace(id=eid, state=state, extra=extra), wall=wall, acked_at=None)


def test_whose_fall_in_words():
    assert whose({"member": "Grandma", "person": 2}) == "Grandma"
    assert whose({"member": None, "household": {"visitor": True}, "person": 4}) == "a visitor"
    assert whose({"person": 3}) == "person 3"
    assert whose({}) is None


def test_the_report_names_whose_fall_it_was():
    marks = event_marks([stored("a", "falling", T0, person=2, member="Grandma"),
                         stored("a", "on_floor", T0 + 2, person=2, member="Grandma"),
                         stored("b", "falling", T0 + 600, person=5, member=None, household={"visitor": True}),
                         stored("c", "on_floor", T0 + 900)])
    falls = episodes(marks)
    assert [f.who for f in falls] == ["Grandma", "a visitor", None]
    series = AngleSeries.from_rows([T0, T0 + 1], {"theta_kn_l": [5.0, 6.0]})
    text = day_report(series, falls, DAY, TZ, robot="r1", sources="test", now=T0 + 3600)
    assert "<td>fall 1 (Grandma)</td>" in text and "<td>fall 2 (a visitor)</td>" in text
    assert "<td>fall 3</td>" in text
