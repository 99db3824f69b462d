"""`posed events` (the command, as a process) on a real journal of a real fall (urfd_04 replayed through the fit
and the fall detector into an EventJournal) and on a journal of an older posed:

* an alarm raised after a restart (``restored``) and one raised with no camera frame (``without_frames_s``)
  say so on their line;
* a journal written before hook delivery was recorded (no hooks columns; a reading command does not migrate
  it) shows its messages' hooks as "not kept", never "pending" (which said the hooks were still to run)."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from posed.commands.falls import detect, fit_frames
from posed.daemon.config import load_config
from posed.daemon.outbox.journal import EventJournal
from posed.landmarks import read_recording

ROOT = Path(__file__).resolve().parents[2]
GEOMETRY = ["falls.camera_height_m=0.85", "falls.camera_tilt_deg=0", "falls.camera_roll_deg=0"]
OLD_SCHEMA = """CREATE TABLE messages (event_id TEXT NOT NULL, state TEXT NOT NULL, robot TEXT NOT NULL,
    wall REAL NOT NULL, t_detect REAL NOT NULL, body TEXT NOT NULL, published_at REAL, acked_at REAL,
    PRIMARY KEY (event_id, state));"""


@pytest.fixture(scope="module")
def messages(shared_data):
    cfg = load_config(None, overrides=GEOMETRY)
    header, frames, _ = read_recording(shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl")
    out = [ev for _f, _r, msgs in detect(cfg, header, fit_frames(cfg, header, frames)) for ev in msgs]
    assert [e.state for e in out][-1] == "on_floor"
    return out


def _events(journal: Path) -> list[str]:
    r = subprocess.run([sys.executable, "-m", "posed.cli", "events", "--journal", str(journal)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.splitlines()


def test_restored_and_frameless_alarms_are_said(messages, tmp_path):
    last = messages[-1]
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as j:
        for ev in messages:
            j.append(ev, hooks_outcome="no_hooks")
        j.append(dataclasses.replace(last, state="alarm", extra={**last.extra, "without_frames_s": 8.94}),
                 hooks_outcome="no_hooks")
        j.append(dataclasses.replace(last, id="f" * 32, state="alarm", extra={
            **last.extra, "restored": {"at_unix": 1.8e9, "last_state": "on_floor", "due_unix": 1.8e9 + 9}}),
            hooks_outcome="no_hooks")
    lines = _events(path)
    alarms = [line for line in lines if " alarm " in line]
    assert len(alarms) == 2
    assert any(line.endswith("[raised with no camera frame for 9 s]") for line in alarms), alarms
    assert any(line.endswith("[taken back after a restart (was on_floor)]") for line in alarms), alarms
    assert not any("[" in line for line in lines if " alarm " not in line)


def test_an_old_journal_s_hooks_are_not_kept_rather_than_pending(messages, tmp_path):
    path = tmp_path / "events.sqlite3"
    db = sqlite3.connect(path)
    db.executescript(OLD_SCHEMA)
    for i, ev in enumerate(messages):
        db.execute("INSERT INTO messages VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                   (ev.id, ev.state, ev.robot, 1.8e9 + i, ev.t_detect, json.dumps(ev.to_json()), 1.8e9 + i, None))
    db.commit()
    db.close()
    rows = [line for line in _events(path) if messages[0].id[:12] in line]
    assert len(rows) == len(messages)
    assert all(" not kept " in line and "pending" not in line for line in rows), rows
