"""The event journal held locked by another process (an sqlite3 shell left with a transaction open, a backup
tool): the real SQLite file, locked by a real second process with BEGIN EXCLUSIVE.

Before the fix, each write waited 5 s for the lock (SQLite's busy timeout), which is the watchdog's
``pipeline.stuck_after_s``: the real daemon's publisher was killed as stuck again and again while the lock was
held (measured: restarted every ~30 s, each start taking 25 s) and the journal logged ``journal_unavailable``
and ``journal_recovered`` once a second each (103 lines in 70 s). Now a write gives up after BUSY_TIMEOUT_S,
the message waits in memory (still returned, republished), the trouble is said once with its fix, and
everything is written once the lock is released."""

from __future__ import annotations

import subprocess
import sys
import time

import structlog

from posed.daemon.config.schema import load_config
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.outbox.journal_file import BUSY_TIMEOUT_S
from tests.daemon.test_hook_redelivery import message

LOCKER = """
import sqlite3, sys
db = sqlite3.connect(sys.argv[1], isolation_level=None)
db.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
sys.stdin.readline()
db.execute("COMMIT")
"""


def test_a_journal_locked_by_another_process_never_blocks_the_publisher_for_long(tmp_path):
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as journal:
        journal.append(message("falling", "before"))
    stuck_after_s = load_config(None).pipeline.stuck_after_s
    locker = subprocess.Popen([sys.executable, "-c", LOCKER, str(path)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert locker.stdout.readline().strip() == "locked"
        with structlog.testing.capture_logs() as logged:
            journal = EventJournal(path)
            slowest = 0.0
            for i in range(10):                        # ten seconds of a publisher: events, marks, status reads
                t0 = time.monotonic()
                journal.append(message("on_floor", f"e{i}"))
                journal.mark_published(f"e{i}")
                journal.unacknowledged()
                slowest = max(slowest, time.monotonic() - t0)
            assert {e.id for e in journal.unacknowledged()} >= {"before"} | {f"e{i}" for i in range(10)}
            assert not journal.healthy and "locked" in journal.last_error
        print(f"slowest publisher step with the journal locked: {slowest:.2f} s")
        assert slowest < stuck_after_s / 2                # each write waits BUSY_TIMEOUT_S, a step a few of them
        assert BUSY_TIMEOUT_S * 3 < stuck_after_s / 2
        said = [x for x in logged if x["event"] == "journal_unavailable"]
        assert len(said) == 1 and "another process holds the journal locked" in said[0]["fix"], said
        assert not [x for x in logged if x["event"] == "journal_recovered"]
    finally:
        locker.communicate("\n", timeout=10)
    with structlog.testing.capture_logs() as logged:
        assert journal.retry()
    assert [x["event"] for x in logged] == ["journal_recovered"]
    journal.close()
    with EventJournal(path) as again:
        assert len(again.query()) == 11
