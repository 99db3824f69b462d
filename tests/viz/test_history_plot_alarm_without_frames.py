"""`posed plot history` on a real history and journal of a real fall (urfd_04 replayed through the fit and the
fall detector into the daemon's AngleHistory and EventJournal) whose ALARM came after the recording ended (no
frame, so no stored sample, after the fall): the plot's fall is the whole event — "fall → on the floor →
ALARM", said to be raised with no camera frame — not just "fall" cut at the last stored sample, and its note
wraps inside the picture."""

from __future__ import annotations

import dataclasses
import datetime as dt
from zoneinfo import ZoneInfo

import pytest

from posed import cli
from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.history.store import AngleHistory
from posed.daemon.outbox.journal import EventJournal
from posed.landmarks import read_recording
from posed.viz import plots
from tests.viz.day import GEOMETRY

TZ = ZoneInfo("Europe/Berlin")


@pytest.fixture(scope="module")
def state(tmp_path_factory, shared_data):
    folder = tmp_path_factory.mktemp("frameless")
    cfg = load_config(None, overrides=GEOMETRY)
    start = dt.datetime(2026, 12, 6, 22, 31, tzinfo=TZ).timestamp()
    header, frames, _ = read_recording(shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl")
    clock = {"now": start}
    with AngleHistory(folder / "history.sqlite3", cfg.falls) as hist, \
            EventJournal(folder / "events.sqlite3", clock=lambda: clock["now"]) as journal:
        last = None
        for frame, result, messages in detect(cfg, header, fit_frames(cfg, header, frames)):
            clock["now"] = start + frame.t
            hist.add(result, wall=clock["now"])
            for ev in messages:
                last = journal.append(ev)
        assert last is not None and last.state == "on_floor"
        clock["now"] += 9.0        # the recording ended: the detector's alarm without frames, as the daemon sends it
        journal.append(dataclasses.replace(last, state="alarm", extra={**last.extra, "without_frames_s": 9.0}))
    return folder


def test_the_alarm_after_the_last_sample_is_part_of_the_plotted_fall(state, tmp_path, monkeypatch):
    drawn = []
    real = plots.angle_figure

    def spy(*args, **kwargs):
        fig = real(*args, **kwargs)
        drawn.append(fig)
        return fig

    monkeypatch.setattr(plots, "angle_figure", spy)
    out = tmp_path / "h.png"
    assert cli.main(["plot", "history", "--db", str(state / "history.sqlite3"), "--since", "2026-12-06",
                     "--until", "2026-12-07", "--tz", "Europe/Berlin", "-o", str(out)]) == 0
    assert out.stat().st_size > 0 and drawn
    fig = drawn[-1]
    notes = [t.get_text() for t in fig.texts if t.get_text().startswith(("fall 1:", "    "))]
    text = " ".join(n.strip() for n in notes)
    assert "fall → on the floor → ALARM" in text, notes
    assert "ALARM raised with no camera frame for 9 s" in text, notes
    fig.canvas.draw()
    width = fig.bbox.width
    renderer = fig.canvas.get_renderer()
    for t in fig.texts:
        if t.get_text() in notes:
            assert t.get_window_extent(renderer).x1 <= width, f"note cut at the right edge: {t.get_text()!r}"
