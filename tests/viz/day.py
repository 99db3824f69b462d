"""A day of history made by replaying real recordings through the product's own classes: the fit as the
fitting stage runs it and the fall detector as the publisher stage runs it (``posed.commands.falls``), the
angles into ``AngleHistory`` and the event messages into ``EventJournal`` with the clock of the day."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.history.store import AngleHistory
from posed.daemon.outbox.journal import EventJournal
from posed.landmarks import read_recording

# (clip, local time it starts) — urfd_04 is a fall that ends on the floor, the adl clips are daily activities
SESSIONS = (("urfd_16_adl", "08:10:00"), ("urfd_04_fall", "10:31:05"), ("urfd_22_adl", "14:02:30"),
            ("urfd_02_fall", "17:45:10"), ("urfd_30_adl", "19:20:00"))
GEOMETRY = ["falls.camera_height_m=0.85", "falls.camera_tilt_deg=0", "falls.camera_roll_deg=0"]


def build_day(folder: Path, data: Path, day: dt.date, tz: dt.tzinfo, ack_first: bool = True) -> dict:
    """history.sqlite3 and events.sqlite3 in ``folder``; returns what was written (event ids, times)."""
    cfg = load_config(None, overrides=GEOMETRY)
    written: dict = {"events": [], "rows": 0, "starts": []}
    folder.mkdir(parents=True, exist_ok=True)
    with AngleHistory(folder / "history.sqlite3", cfg.falls) as hist:
        for clip, at in SESSIONS:
            start = dt.datetime.combine(day, dt.time.fromisoformat(at), tz).timestamp()
            written["starts"].append(start)
            header, frames, _ = read_recording(data / "falls" / "urfd_dev" / f"{clip}.landmarks.jsonl")
            clock = {"now": start}
            with EventJournal(folder / "events.sqlite3", clock=lambda c=clock: c["now"]) as journal:
                for frame, result, messages in detect(cfg, header, fit_frames(cfg.fitting, header, frames)):
                    clock["now"] = start + frame.t
                    written["rows"] += hist.add(result, wall=start + frame.t)
                    for ev in messages:
                        journal.append(ev)
                        written["events"].append((ev.id, ev.state, start + frame.t))
    if ack_first and written["events"]:
        first = written["events"][0]
        with EventJournal(folder / "events.sqlite3", clock=lambda: first[2] + 95.0) as journal:
            journal.acknowledge(first[0])
    return written
