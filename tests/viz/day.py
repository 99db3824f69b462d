"""A day of history made by replaying real recordings through the product's own classes: the fit as the
fitting stage runs it and the fall detector as the publisher stage runs it (``posed.commands.falls``), the
angles into ``AngleHistory``, every frame into the minutes posed watched (``WatchLog``, as the publisher's
recorder counts them) and the event messages into ``EventJournal`` with the clock of the day. posed runs from
07:00 to 01:00 — off for the 6 hours from 01:00 — and between the recordings it watches an empty room (one
frame a second, nobody in view)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.history.store import AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.daemon.outbox.journal import EventJournal
from posed.landmarks import read_recording

# (clip, local time it starts) — urfd_04 is a fall that ends on the floor, the adl clips are daily activities
SESSIONS = (("urfd_16_adl", "08:10:00"), ("urfd_04_fall", "10:31:05"), ("urfd_22_adl", "14:02:30"),
            ("urfd_02_fall", "17:45:10"), ("urfd_30_adl", "19:20:00"))
GEOMETRY = ["falls.camera_height_m=0.85", "falls.camera_tilt_deg=0", "falls.camera_roll_deg=0"]
OFF = ("01:00:00", "07:00:00")       # posed not running (local time)


def build_day(folder: Path, data: Path, day: dt.date, tz: dt.tzinfo, ack_first: bool = True) -> dict:
    """history.sqlite3 and events.sqlite3 in ``folder``; returns what was written (event ids, times)."""
    cfg = load_config(None, overrides=GEOMETRY)
    written: dict = {"events": [], "rows": 0, "starts": []}
    folder.mkdir(parents=True, exist_ok=True)
    midnight = dt.datetime.combine(day, dt.time(0), tz).timestamp()
    off = [dt.datetime.combine(day, dt.time.fromisoformat(t), tz).timestamp() for t in OFF]
    written["off"] = tuple(off)
    with AngleHistory(folder / "history.sqlite3", cfg.falls) as hist, \
            WatchLog(folder / "history.sqlite3") as watched:
        empty_from = midnight
        for clip, at in SESSIONS:
            start = dt.datetime.combine(day, dt.time.fromisoformat(at), tz).timestamp()
            _empty_room(watched, empty_from, start, off)
            written["starts"].append(start)
            header, frames, _ = read_recording(data / "falls" / "urfd_dev" / f"{clip}.landmarks.jsonl")
            clock = {"now": start}
            with EventJournal(folder / "events.sqlite3", clock=lambda c=clock: c["now"]) as journal:
                for frame, result, messages in detect(cfg, header, fit_frames(cfg, header, frames)):
                    clock["now"] = start + frame.t
                    written["rows"] += hist.add(result, wall=start + frame.t)
                    watched.add(start + frame.t, person=result.ok or result.reason != "no person",
                                fitted=result.ok)
                    for ev in messages:
                        journal.append(ev)
                        written["events"].append((ev.id, ev.state, start + frame.t))
            empty_from = start + frames[-1].t + 1.0
        _empty_room(watched, empty_from, midnight + 86400.0, off)
    if ack_first and written["events"]:
        first = written["events"][0]
        with EventJournal(folder / "events.sqlite3", clock=lambda: first[2] + 95.0) as journal:
            journal.acknowledge(first[0])
    return written


def _empty_room(watched: WatchLog, start: float, end: float, off: list[float]) -> None:
    """posed watching a room with nobody in it, one frame a second, except while it is off."""
    t = start
    while t < end:
        if not off[0] <= t < off[1]:
            watched.add(t, person=False, fitted=False)
        t += 1.0
