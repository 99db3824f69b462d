"""A huge backlog of hook deliveries at a start (the red-team of durable hooks), with the real journal (SQLite)
and a real hook program:

* 3000 alarms a week old whose hooks never finished (a hook cut off or dropped from a full queue day after day):
  before, every one was handed to the hook again at the start (the carer phoned 3000 times: 408 calls in the
  first 20 s), the full queue dropped them back to pending for the next start, and every skipped message cost one
  fsync'd write (5000 rows: 7.6 s before the publisher could start). Now the newest REDELIVER_MAX_MESSAGES are
  handed again, the rest marked stale and named in one error line, with a bounded number of writes;
* a new fall while the backlog runs: its message runs before the redelivered ones (before, it waited behind
  them: with a 30 s phone-call hook, 100 queued messages meant 50 minutes)."""

from __future__ import annotations

import sqlite3
import time
from pathlib import Path

from posed.daemon.outbox import journal_file
from posed.daemon.outbox import journal_rows as rows
from posed.daemon.outbox.delivery import REDELIVER_MAX_MESSAGES, EventOutbox
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from tests.daemon.fakes import RecordingLog
from tests.daemon.test_hook_redelivery import hooks_config, hooks_state, message, starts, until

WEEK_S = 7 * 86400.0


def _week_of_alarms(path: Path, n: int) -> None:
    """``n`` alarms over the last week, journalled by runs whose hooks never finished with them."""
    now = time.time()
    with EventJournal(path) as journal:
        db = journal._db
        with journal_file.Transaction(db):
            for i in range(n):
                stored = rows.StoredEvent(message("alarm", f"a{i:05d}"), now - WEEK_S + i * (WEEK_S / n), None,
                                          None)
                rows.insert(db, stored)


def _commits(path: Path) -> tuple[list[str], object]:
    seen: list[str] = []

    def connect(p: Path) -> sqlite3.Connection:
        db = journal_file.default_connect(p)
        db.set_trace_callback(lambda sql: seen.append(sql) if sql.strip().upper() == "COMMIT" else None)
        return db

    return seen, connect


def test_a_week_of_undone_alarms_hands_only_the_newest_to_the_hook_and_says_so_once(tmp_path):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    n = 3000
    _week_of_alarms(path, n)
    commits, connect = _commits(path)
    log = RecordingLog()
    box = EventOutbox(EventJournal(path, connect=connect), HookRunner(hooks_config(tmp_path, "rec")),
                      lambda obj: True, log, 30.0)
    at_start = len(commits)
    try:
        assert box.hooks.wait_idle(60)
    finally:
        box.close()
    assert box.redelivery["redelivered"] == REDELIVER_MAX_MESSAGES
    assert box.redelivery["backlog"] == n - REDELIVER_MAX_MESSAGES
    ran = starts(rec)
    assert [i for i, *_ in ran] == [f"a{i:05d}" for i in range(n - REDELIVER_MAX_MESSAGES, n)]   # newest, in order
    assert all(s == "alarm" and redelivered == "1" for _, s, _, redelivered in ran)
    (backlog,) = [f for lv, e, f in log.lines if e == "hook_redelivery_backlog"]
    assert backlog["count"] == backlog["alarms"] == n - REDELIVER_MAX_MESSAGES and "fix" in backlog
    assert log.events("error") == ["hook_redelivery_backlog"]
    assert at_start <= 5, at_start              # the marks in one write, not one fsync per message
    state = hooks_state(path)
    assert list(state.values()).count("stale") == n - REDELIVER_MAX_MESSAGES
    assert list(state.values()).count("ok") == REDELIVER_MAX_MESSAGES
    # the next start hands nothing again
    again = EventOutbox(EventJournal(path), HookRunner(hooks_config(tmp_path, "rec")), lambda obj: True,
                        RecordingLog(), 30.0)
    again.close()
    assert again.redelivery["redelivered"] == 0 and len(starts(rec)) == REDELIVER_MAX_MESSAGES


def test_a_new_fall_runs_before_the_messages_handed_again(tmp_path):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    _week_of_alarms(path, 5)
    Path(f"{rec}.gate").touch()                    # the hook hangs on its first run, like a phone call
    box = EventOutbox(EventJournal(path), HookRunner(hooks_config(tmp_path, "rec")), lambda obj: True,
                      RecordingLog(), 30.0)
    try:
        until(lambda: starts(rec), 10, "the first redelivered run")
        box.post(message("alarm", "now"))
        Path(f"{rec}.gate").unlink()
        assert box.hooks.wait_idle(30)
    finally:
        box.close()
    assert [i for i, *_ in starts(rec)] == ["a00000", "now", "a00001", "a00002", "a00003", "a00004"]
