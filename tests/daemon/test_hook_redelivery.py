"""Durable hook delivery, with the real journal (SQLite) and real hook processes: the journal records which
hooks are done with each message; a run cut off by a shutdown, or a message still waiting then, is handed to
the hooks again when the next EventOutbox is made, oldest first, its attempt numbers going on; what is done is
not run again; a 'falling'/'on_floor'/'recovered' older than the bound is skipped (logged, marked stale), an
'alarm' is handed again at any age; a journal written before these columns is migrated.

The kill -9 and SIGTERM of a real daemon: tests/daemon/test_hook_redelivery_e2e.py."""

from __future__ import annotations

import json
import sqlite3
import time
from pathlib import Path

from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.outbox import journal_rows
from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.hooks import HookRunner, hook_key
from posed.daemon.outbox.journal import EventJournal
from posed.falls.event import FallEvent
from tests.daemon.fakes import RecordingLog

# a hook that notes each run (id, state, attempt, redelivered) and waits while its gate file exists
HOOK = """\
rec="$1"
echo "start $POSED_EVENT_ID $POSED_EVENT_STATE $POSED_HOOK_ATTEMPT $POSED_HOOK_REDELIVERED" >> "$rec"
while [ -e "$rec.gate" ]; do sleep 0.02; done
echo "end $POSED_EVENT_ID $POSED_EVENT_STATE $POSED_HOOK_ATTEMPT" >> "$rec"
exit "${HOOK_EXIT:-0}"
"""

# the schema of the journal as posed wrote it before hook delivery and ack `by` were recorded (verbatim)
OLD_SCHEMA = """
CREATE TABLE IF NOT EXISTS messages (
    event_id     TEXT NOT NULL,
    state        TEXT NOT NULL,
    robot        TEXT NOT NULL,
    wall         REAL NOT NULL,      -- unix seconds when the detector's message was journalled
    t_detect     REAL NOT NULL,      -- capture clock (seconds)
    body         TEXT NOT NULL,      -- FallEvent.to_json()
    published_at REAL,               -- unix seconds of the first publication, NULL = never published
    acked_at     REAL,               -- unix seconds of the acknowledgement, NULL = not acknowledged
    PRIMARY KEY (event_id, state)
);
CREATE INDEX IF NOT EXISTS messages_wall ON messages (wall);
CREATE INDEX IF NOT EXISTS messages_unacked ON messages (acked_at) WHERE acked_at IS NULL;
"""
OLD_INSERT = ("INSERT INTO messages (event_id, state, robot, wall, t_detect, body, published_at, acked_at) "
              "VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (event_id, state) DO UPDATE SET "
              "body = excluded.body, wall = excluded.wall, t_detect = excluded.t_detect")


def message(state: str, id_: str = "e1", t: float = 10.0) -> FallEvent:
    return FallEvent(id=id_, robot="r1", state=state, t_onset=t - 1.0, t_impact=t - 0.4, t_detect=t,
                     confidence=0.8, features=("pelvis_descent_fast",))


def hooks_config(tmp_path: Path, *recs: str, retries: int = 1) -> HooksConfig:
    script = tmp_path / "hook.sh"
    script.write_text(HOOK)
    return HooksConfig(retry_delay_s=0.0, on_event=tuple(
        HookConfig(argv=("/bin/sh", str(script), str(tmp_path / rec)), timeout_s=30, retries=retries)
        for rec in recs))


def lines(path: Path) -> list[list[str]]:
    return [line.split() for line in path.read_text().splitlines()] if path.exists() else []


def starts(path: Path) -> list[tuple[str, str, str, str]]:
    """(id, state, POSED_HOOK_ATTEMPT, POSED_HOOK_REDELIVERED) of each run started, in order."""
    return [tuple(x[1:]) for x in lines(path) if x[0] == "start"]


def until(pred, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if v := pred():
            return v
        time.sleep(0.02)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def start(path: Path, cfg: HooksConfig, journal_clock=time.time) -> tuple[EventOutbox, RecordingLog]:
    """What the publisher stage does at its start: the journal, the hooks, the outbox."""
    log = RecordingLog()
    box = EventOutbox(EventJournal(path, clock=journal_clock), HookRunner(cfg), lambda obj: True, log, 30.0)
    return box, log


def hooks_state(path: Path) -> dict[tuple[str, str], str | None]:
    with sqlite3.connect(path) as db:
        return {(i, s): o for i, s, o in db.execute("SELECT event_id, state, hooks_outcome FROM messages")}


def test_a_shutdown_leaves_runs_pending_and_the_next_start_runs_them_in_order(tmp_path):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    cfg = hooks_config(tmp_path, "rec")
    Path(f"{rec}.gate").touch()                          # the first run hangs, like a phone call
    box, log = start(path, cfg)
    for state in ("falling", "on_floor", "alarm"):
        box.post(message(state))
    until(lambda: starts(rec), 10, "the falling hook to start")
    box.close(hook_timeout_s=0.2)                       # as the publisher's close on SIGTERM
    assert starts(rec) == [("e1", "falling", "1", "0")]
    assert hooks_state(path) == {("e1", "falling"): None, ("e1", "on_floor"): None, ("e1", "alarm"): None}

    Path(f"{rec}.gate").unlink()
    box, log = start(path, cfg)                         # the next start
    assert box.redelivery["redelivered"] == 3
    assert box.hooks.wait_idle(20)
    assert starts(rec)[1:] == [("e1", "falling", "2", "1"), ("e1", "on_floor", "1", "1"),
                               ("e1", "alarm", "1", "1")]   # oldest first; the cut-off run counted
    [(_, _, fields)] = [x for x in log.lines if x[1] == "hooks_redelivered"]
    assert [(m["state"], m["attempt"]) for m in fields["messages"]] == [("falling", 2), ("on_floor", 1), ("alarm", 1)]
    box.close()
    assert set(hooks_state(path).values()) == {"ok"}

    box, log = start(path, cfg)                         # done: never again
    assert box.redelivery["redelivered"] == 0 and box.journal.hooks_pending() == []
    box.close()
    assert len(starts(rec)) == 4


def test_only_the_hooks_not_done_run_again(tmp_path):
    path, fast, slow = tmp_path / "events.sqlite3", tmp_path / "fast", tmp_path / "slow"
    cfg = hooks_config(tmp_path, "fast", "slow")
    Path(f"{slow}.gate").touch()
    box, _ = start(path, cfg)
    box.post(message("alarm"))
    until(lambda: lines(fast) and starts(slow), 10, "both hooks to start")
    until(lambda: len(lines(fast)) == 2, 10, "the fast hook to finish")
    box.close(hook_timeout_s=0.2)
    with sqlite3.connect(path) as db:
        runs = dict(((h, (a, o)) for h, a, o in db.execute("SELECT hook, attempts, outcome FROM hook_runs")))
    assert runs == {box.hooks.keys[0]: (1, "ok"), box.hooks.keys[1]: (1, None)}

    Path(f"{slow}.gate").unlink()
    box, _ = start(path, cfg)
    assert box.hooks.wait_idle(20)
    box.close()
    assert starts(fast) == [("e1", "alarm", "1", "0")]                       # done: not run again
    assert starts(slow) == [("e1", "alarm", "1", "0"), ("e1", "alarm", "2", "1")]
    assert hooks_state(path) == {("e1", "alarm"): "ok"}


def test_a_hook_that_gave_up_is_done(tmp_path, monkeypatch):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    monkeypatch.setenv("HOOK_EXIT", "3")
    cfg = hooks_config(tmp_path, "rec", retries=1)
    box, _ = start(path, cfg)
    box.post(message("alarm"))
    assert box.hooks.wait_idle(20)
    until(lambda: hooks_state(path)[("e1", "alarm")], 5, "the message marked done")
    box.close()
    assert hooks_state(path) == {("e1", "alarm"): "gave_up"}
    assert [a for _, _, a, _ in starts(rec)] == ["1", "2"]
    box, _ = start(path, cfg)
    box.close()
    assert box.redelivery["redelivered"] == 0 and len(starts(rec)) == 2


def test_old_messages_are_skipped_and_logged_but_an_alarm_is_handed_again_at_any_age(tmp_path):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    now = time.time()
    # journalled by a run of the publisher that died before its hooks ran: a fall two hours ago, one 10 min ago
    for age, id_ in ((7200.0, "old"), (600.0, "new")):
        with EventJournal(path, clock=lambda age=age: now - age) as journal:
            for state in ("falling", "on_floor", "alarm", "recovered"):
                journal.append(message(state, id_))
    box, log = start(path, hooks_config(tmp_path, "rec"))
    assert box.hooks.wait_idle(20)
    box.close()
    assert box.redelivery == {"redelivered": 5, "stale": 3, "backlog": 0, "no_hooks": 0, "finished": 0}
    assert [(i, s) for i, s, _, _ in starts(rec)] == [
        ("old", "alarm"), ("new", "falling"), ("new", "on_floor"), ("new", "alarm"), ("new", "recovered")]
    skipped = [f for _, e, f in log.lines if e == "hook_redelivery_skipped"]
    assert [(f["id"], f["state"], f["outcome"]) for f in skipped] == [
        ("old", "falling", "stale"), ("old", "on_floor", "stale"), ("old", "recovered", "stale")]
    assert all(7100 < f["age_s"] < 7300 and "tells of the past" in f["reason"] for f in skipped)
    state = hooks_state(path)
    assert state[("old", "falling")] == "stale" and state[("old", "alarm")] == "ok"
    assert {state[("new", s)] for s in ("falling", "on_floor", "alarm", "recovered")} == {"ok"}


def test_without_hooks_messages_are_done_and_pending_ones_are_skipped_with_a_log_line(tmp_path):
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as journal:
        journal.append(message("alarm", "before"))         # hooks were configured then, and cut off
    box, log = start(path, HooksConfig())
    box.post(message("falling", "now"))
    box.close()
    assert hooks_state(path) == {("before", "alarm"): "no_hooks", ("now", "falling"): "no_hooks"}
    assert [(f["id"], f["outcome"]) for _, e, f in log.lines if e == "hook_redelivery_skipped"] == [
        ("before", "no_hooks")]


def test_hook_keys_follow_the_argv():
    a, b = ("/bin/notify", "--to", "anna"), ("/bin/notify", "--to", "ben")
    assert hook_key(a) == hook_key(list(a)) != hook_key(b)
    assert hook_key(a, [hook_key(a)]) == hook_key(a) + "#2"
    runner = HookRunner(HooksConfig(on_event=(HookConfig(argv=a), HookConfig(argv=b), HookConfig(argv=a))))
    assert runner.keys == (hook_key(a), hook_key(b), hook_key(a) + "#2")
    runner.close()


def _old_journal(path: Path, now: float) -> None:
    """events.sqlite3 as the posed before this change wrote it (its schema and its insert, verbatim)."""
    db = sqlite3.connect(path)
    db.execute("PRAGMA journal_mode=WAL")
    db.executescript(OLD_SCHEMA)
    for id_, state, age, acked in (("old", "falling", 7200.0, True), ("old", "alarm", 7100.0, False),
                                   ("new", "on_floor", 120.0, False), ("new", "alarm", 60.0, False)):
        e = message(state, id_)
        db.execute(OLD_INSERT, (e.id, e.state, e.robot, now - age, e.t_detect, json.dumps(e.to_json()), now - age,
                                now - age + 1 if acked else None))
    db.commit()
    db.close()


def test_an_old_journal_is_read_as_it_is_and_migrated_by_the_daemon(tmp_path, capsys):
    path, rec = tmp_path / "events.sqlite3", tmp_path / "rec"
    now = time.time()
    _old_journal(path, now)
    # a reader (posed events) opens it read-only: no migration, the new fields read as null
    with EventJournal(path, readonly=True) as reader:
        stored = reader.query()
    assert [(s.event.id, s.event.state, s.acked_by, s.hooks_outcome) for s in stored] == [
        ("old", "falling", None, None), ("old", "alarm", None, None), ("new", "on_floor", None, None),
        ("new", "alarm", None, None)]
    assert stored[0].acked_at is not None
    with sqlite3.connect(path) as db:
        assert "hooks_done_at" not in {r[1] for r in db.execute("PRAGMA table_info(messages)")}

    # the daemon opens it: columns added; rows older than the bound untracked, the newer ones pending and run
    box, log = start(path, hooks_config(tmp_path, "rec"))
    assert box.hooks.wait_idle(20)
    assert [(i, s) for i, s, _, _ in starts(rec)] == [("new", "on_floor"), ("new", "alarm")]
    assert box.journal.acknowledge("new", "alarm", by="daughter") == 1
    box.close()
    migrated = [json.loads(x) for x in capsys.readouterr().out.splitlines() if "journal_migrated" in x]
    assert len(migrated) == 1 and migrated[0]["added_columns"] == ["acked_by", "hooks_done_at", "hooks_outcome"]
    assert migrated[0]["hooks_untracked"] == 2 and migrated[0]["hooks_pending"] == 2
    assert hooks_state(path) == {("old", "falling"): "untracked", ("old", "alarm"): "untracked",
                                 ("new", "on_floor"): "ok", ("new", "alarm"): "ok"}
    with EventJournal(path, readonly=True) as reader:
        by = {(s.event.id, s.event.state): (s.acked_at is not None, s.acked_by) for s in reader.query()}
    assert by == {("old", "falling"): (True, None), ("old", "alarm"): (False, None),
                  ("new", "on_floor"): (False, None), ("new", "alarm"): (True, "daughter")}
    # opened again: nothing more to migrate, nothing run again
    box, log = start(path, hooks_config(tmp_path, "rec"))
    box.close()
    assert "journal_migrated" not in capsys.readouterr().out and len(starts(rec)) == 2


def test_hook_progress_waits_in_memory_while_the_journal_cannot_write(tmp_path):
    """While the journal cannot open its file (a disk error), the message and its hooks' progress wait in
    memory, are seen by hooks_pending, and are written when the file can be written again."""
    from posed.daemon.outbox.journal_file import default_connect

    down = {"on": True}

    def connect(p):
        if down["on"]:
            raise sqlite3.OperationalError("disk I/O error")
        return default_connect(p)

    path = tmp_path / "events.sqlite3"
    journal = EventJournal(path, connect=connect)
    assert not journal.healthy
    journal.append(message("alarm"))
    journal.hook_started("e1", "alarm", "k", 1)
    [(stored, runs)] = journal.hooks_pending()
    assert stored.key == ("e1", "alarm") and runs == {"k": journal_rows.HookRun(1, None)}
    journal.hook_finished("e1", "alarm", "k", "ok")
    assert journal.hooks_pending()[0][1] == {"k": journal_rows.HookRun(1, "ok")}
    journal.mark_hooks_done("e1", "alarm", "ok")
    assert journal.hooks_pending() == []
    down["on"] = False
    assert journal.retry()
    journal.close()
    assert hooks_state(path) == {("e1", "alarm"): "ok"}
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT hook, attempts, outcome FROM hook_runs").fetchall() == [("k", 1, "ok")]
