"""A fall open when the daemon was stopped (``systemctl restart``, an upgrade: SIGTERM between ``on_floor`` and
``alarm``), and a state directory that is read-only at the restart (a file system remounted read-only after an
error): a real tmpfs remounted read-only, a real journal written and closed by a real second process, the real
detector's messages of a real fall (urfd_dev's urfd_04).

Before the fix SQLite could not open the journal there (a closed WAL journal has no ``-shm`` file, and none can be
created) and every read returned only what waited in memory: the open fall was not restored and its alarm never
came, with nothing said but ``journal_unavailable``; the messages on the file were not republished, and an
acknowledgement of one was dropped as unknown. Now they are read from a copy of the file (and its write-ahead
log, when a kill -9 left one)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.daemon.outbox.journal import EventJournal
from posed.daemon.stages.restored_falls import RestoredFalls
from tests.conftest import ROOT
from tests.daemon import restore_util as ru
from tests.daemon.fakes import RecordingLog
from tests.daemon.test_restored_falls import _before_restart

WRITER = """
import json, os, sys
from posed.daemon.outbox.journal import EventJournal
from posed.falls.event import FallEvent
journal = EventJournal(sys.argv[1])
for obj in json.loads(sys.stdin.read()):
    journal.append(FallEvent.from_json(obj))
if sys.argv[2] == "killed":
    os._exit(0)         # no close, no checkpoint: as a kill -9 (the messages in the -wal, the -shm left)
journal.close()         # as the publisher closes it at a stop
"""


@pytest.mark.parametrize("how", ["stopped", "killed"])
def test_a_read_only_state_dir_at_the_restart_still_restores_the_open_fall(tmp_path, tmpfs, shared_data, how):
    alarm_s = 30.0
    before = _before_restart(shared_data, EventJournal(tmp_path / "scratch" / "events.sqlite3"), alarm_s=alarm_s)
    disk = tmpfs("2m")
    path = disk / "state" / "events.sqlite3"
    subprocess.run([sys.executable, "-c", WRITER, str(path), how], input=json.dumps([e.to_json() for e in before]),
                   text=True, check=True, cwd=ROOT, timeout=60)
    assert Path(f"{path}-shm").exists() == (how == "killed")
    subprocess.run(["mount", "-o", "remount,ro", str(disk)], check=True)
    try:
        journal = EventJournal(path)
        assert [e.state for e in journal.unacknowledged()] == ["falling", "on_floor"]    # still republished
        now = time.monotonic()
        log = RecordingLog()
        restored = RestoredFalls.load(journal, ru.config(f"falls.alarm_after_s={alarm_s}").falls, log, now=now)
        (f,) = restored.open
        assert f.id == before[0].id and f.due_unix == before[0].extra["t_impact_unix"] + alarm_s
        (alarm,) = restored.due(f.due)
        assert alarm.id == before[0].id and alarm.state == "alarm"
        stored = journal.append(alarm)                         # kept in memory: the disk is read-only
        assert journal.pending_in_memory == 1 and stored.state == "alarm" and not journal.healthy
        assert journal.acknowledge(before[0].id, "falling") == 1   # a message on the file, acknowledged
        assert [e.state for e in journal.unacknowledged()] == ["on_floor", "alarm"]
    finally:
        subprocess.run(["mount", "-o", "remount,rw", str(disk)], check=True)
    assert journal.retry(), journal.last_error
    assert {(s.event.state, s.acked_at is not None) for s in journal.query()} == {
        ("falling", True), ("on_floor", False), ("alarm", False)}
    journal.close()
