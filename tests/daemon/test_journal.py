"""The event journal: durable before publishing, kept until acknowledged, survives kill -9, disk full, corruption."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from posed.daemon.outbox.journal import EventJournal, JournalError
from posed.falls.event import FallEvent

ROOT = Path(__file__).resolve().parents[3]


def event(state="falling", id_="e1", t=10.0) -> FallEvent:
    return FallEvent(id=id_, robot="r1", state=state, t_onset=t - 1.0, t_impact=t - 0.4, t_detect=t,
                     confidence=0.8, features=("pelvis_descent_fast",), pose={"seq": 3, "t": t, "ok": True})


def test_lifecycle_append_publish_acknowledge(tmp_path):
    clock = iter(range(1000, 2000)).__next__
    with EventJournal(tmp_path / "events.sqlite3", clock=lambda: float(clock())) as j:
        stored = j.append(event())
        assert stored.wall_time.startswith("1970-01-01T00:16:40")
        j.append(event("alarm", t=20.0))
        j.append(event("falling", id_="e2", t=30.0))
        assert [(e.id, e.state) for e in j.unpublished()] == [("e1", "falling"), ("e1", "alarm"), ("e2", "falling")]
        j.mark_published("e1")
        assert [(e.id, e.state) for e in j.unpublished()] == [("e2", "falling")]
        assert len(j.unacknowledged()) == 3
        assert j.acknowledge("e1") == 2
        assert j.acknowledge("nope") == 0
        assert [(e.id, e.state) for e in j.unacknowledged()] == [("e2", "falling")]
        # an update after the acknowledgement needs its own acknowledgement
        j.append(event("recovered", t=40.0))
        assert [(e.id, e.state) for e in j.unacknowledged()] == [("e2", "falling"), ("e1", "recovered")]
        rows = j.query(since=1001.0, until=1002.0)
        assert [(s.event.id, s.event.state) for s in rows] == [("e1", "alarm"), ("e2", "falling")]
        assert [s.event.state for s in j.query(limit=2)] == ["falling", "recovered"]
        assert j.get("e1")[0].event == stored


def test_pragmas_wal_and_full_sync(tmp_path):
    with EventJournal(tmp_path / "events.sqlite3") as j:
        assert j._db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert j._db.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL


CHILD = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {root!r})
    from posed.falls.event import FallEvent
    from posed.daemon.outbox.journal import EventJournal
    j = EventJournal(sys.argv[1])
    j.append(FallEvent(id="k9", robot="r1", state="falling", t_onset=1.0, t_impact=1.5, t_detect=2.0,
                       confidence=0.9, features=("x",)))
    print("written", flush=True)
    time.sleep(60)   # killed here: between the write and the publication
    j.mark_published("k9")
""")


def test_event_survives_kill_9_between_write_and_publish(tmp_path):
    path = tmp_path / "events.sqlite3"
    script = tmp_path / "child.py"
    script.write_text(CHILD.format(root=str(ROOT)))
    proc = subprocess.Popen([sys.executable, str(script), str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "written"
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    assert proc.returncode == -signal.SIGKILL
    with EventJournal(path) as j:
        pending = j.unpublished()
    assert [(e.id, e.state, e.t_detect) for e in pending] == [("k9", "falling", 2.0)]


def test_disk_full_keeps_events_in_memory_and_retries(tmp_path, capsys):
    full = {"on": True}

    def connect(path):  # the real SQLite, with a file that cannot grow while the "disk" is full
        db = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
        if full["on"]:
            pages = db.execute("PRAGMA page_count").fetchone()[0]
            db.execute(f"PRAGMA max_page_count = {max(pages, 6)}")
        return db

    j = EventJournal(tmp_path / "events.sqlite3", connect=connect)
    big = {"blob": "x" * 20000}
    for i in range(5):
        j.append(FallEvent(id=f"f{i}", robot="r1", state="falling", t_onset=None, t_impact=1.0, t_detect=2.0,
                           confidence=0.5, pose=big))
    assert not j.healthy and j.pending_in_memory > 0
    assert "full" in j.last_error
    out = capsys.readouterr().out
    assert "journal_unavailable" in out and "free disk space" in out
    ids = sorted(e.id for e in j.unacknowledged())
    assert ids == [f"f{i}" for i in range(5)]          # nothing lost while the disk is full
    j.mark_published("f0")
    assert "f0" not in {e.id for e in j.unpublished()}
    assert not j.retry()
    full["on"] = False                                  # space freed
    assert j.retry()
    assert j.healthy
    j.close()
    with EventJournal(tmp_path / "events.sqlite3") as again:
        assert sorted(e.id for e in again.unacknowledged()) == ids
        assert "f0" not in {e.id for e in again.unpublished()}


def test_corrupt_file_is_set_aside_and_journal_goes_on(tmp_path, capsys):
    path = tmp_path / "events.sqlite3"
    path.write_bytes(b"this is not a database" * 100)
    j = EventJournal(path, clock=lambda: 1234.0)
    assert "journal_corrupt" in capsys.readouterr().out
    assert (tmp_path / "events.sqlite3.corrupt-1234").is_file()
    j.append(event())
    assert [e.id for e in j.unacknowledged()] == ["e1"]
    j.close()
    sqlite3.connect(path).execute("SELECT count(*) FROM messages").fetchone()


def test_unwritable_folder_keeps_events_in_memory(tmp_path):
    blocker = tmp_path / "state"
    blocker.write_text("a file where the state dir should be")
    j = EventJournal(blocker / "events.sqlite3")
    assert not j.healthy and "cannot create" in j.last_error
    j.append(event())
    assert [e.id for e in j.unacknowledged()] == ["e1"]
    blocker.unlink()
    assert j.retry()
    j.close()
    with EventJournal(blocker / "events.sqlite3") as again:
        assert [e.id for e in again.unacknowledged()] == ["e1"]


def test_concurrent_reader_sees_committed_events(tmp_path):
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as writer:
        writer.append(event())
        t0 = time.monotonic()
        with EventJournal(path) as reader:
            assert [e.id for e in reader.unacknowledged()] == ["e1"]
        assert time.monotonic() - t0 < 5


def test_readonly_reads_without_creating_or_moving_anything(tmp_path, capsys):
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as writer:
        writer.append(event())
    with EventJournal(path, readonly=True) as reader:
        assert [e.id for e in reader.unacknowledged()] == ["e1"]
        with pytest.raises(JournalError, match="read-only"):
            reader.append(event("alarm"))
        with pytest.raises(JournalError, match="read-only"):
            reader.acknowledge("e1")
    with EventJournal(path) as writer:
        assert [e.state for e in writer.unacknowledged()] == ["falling"]

    missing = tmp_path / "state" / "events.sqlite3"
    with pytest.raises(FileNotFoundError, match=str(missing)):
        EventJournal(missing, readonly=True)
    assert not missing.parent.exists()

    corrupt = tmp_path / "corrupt.sqlite3"
    corrupt.write_bytes(b"this is not a database" * 100)
    with pytest.raises(JournalError, match="cannot read the event journal .*corrupt.sqlite3.*recover"):
        EventJournal(corrupt, readonly=True)
    assert corrupt.read_bytes() == b"this is not a database" * 100
    assert not list(tmp_path.glob("*.corrupt-*"))
    assert capsys.readouterr().out == ""            # a reader never logs

    other = tmp_path / "other.sqlite3"
    with sqlite3.connect(other) as db:              # another program's database
        db.execute("CREATE TABLE notes (text TEXT)")
    with pytest.raises(JournalError, match="not an event journal"):
        EventJournal(other, readonly=True)
    assert sqlite3.connect(other).execute("SELECT count(*) FROM sqlite_master").fetchone()[0] == 1

    # the daemon has made the file and not yet committed its table (its first fall event, a moment ago): no
    # event yet, as when there is no file, never "not an event journal" to a reader polling at that moment
    creating = tmp_path / "creating.sqlite3"
    sqlite3.connect(creating).close()               # an empty database: no tables
    with pytest.raises(FileNotFoundError, match="creating it"):
        EventJournal(creating, readonly=True)
    assert sqlite3.connect(creating).execute("SELECT count(*) FROM sqlite_master").fetchone()[0] == 0


def test_a_selection_means_the_same_on_disk_and_in_memory(tmp_path):
    """Messages waiting in memory (disk full) are selected by the same rule as the stored ones."""
    from posed.daemon.outbox import journal_rows as rows
    from posed.daemon.outbox.journal_rows import Selection

    clock = iter(range(1000, 2000)).__next__
    with EventJournal(tmp_path / "events.sqlite3", clock=lambda: float(clock())) as j:
        for i, (id_, state) in enumerate([("e1", "falling"), ("e1", "alarm"), ("e2", "falling"),
                                          ("e3", "on_floor"), ("e3", "recovered")]):
            j.append(event(state, id_, t=10.0 + i))
        j.mark_published("e1")
        j.mark_published("e3", "on_floor")
        j.acknowledge("e1", "falling")
        j.acknowledge("e3")
        assert len(list(rows.select(j._db, Selection()))) == 5
        for sel in (Selection(), Selection(unacked=True), Selection(unpublished=True), Selection(event_id="e3"),
                    Selection(since=1001.0), Selection(until=1002.0), Selection(since=1001.0, until=1003.0,
                                                                                unacked=True),
                    Selection(event_id="e1", unpublished=True)):
            on_disk = [s.key for s in rows.select(j._db, sel)]
            in_memory = [s.key for s in rows.select(j._db, Selection()) if sel.matches(s)]
            assert on_disk == in_memory, sel
        assert [s.key for s in rows.select(j._db, Selection(since=1001.0, until=1003.0, unacked=True))] == \
            [("e1", "alarm"), ("e2", "falling")]
