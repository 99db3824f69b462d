"""A state directory that fails (read-only, full, gone) is a degraded mode, never a stop (issue 34 items 1, 2):
the journal keeps fall-event messages in memory and in the fallback file, which the next start takes back; the
history keeps no rows and says why; the status, STATUS= and the stop say so; ``posed config check`` flags it.

The failures are real OS errors: a state directory below a regular file (ENOTDIR) everywhere, and a read-only
tmpfs (EROFS) where this machine lets the test mount one (root)."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from posed.daemon.history.store import AngleHistory
from posed.daemon.outbox.fallback import FallbackStore, fallback_path
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.outbox.private import private_folder
from posed.daemon.state_check import state_dir_problems
from posed.daemon.supervisor import status_text
from posed.falls.event import FallEvent
from posed.fitting import FitResult
from tests.daemon.plan_stages import FALL_OVERRIDES
from tests.daemon.redteam_util import FileHarness
from tests.daemon.zenoh_util import free_port

ROOT = Path(__file__).resolve().parents[2]


def _event(state: str = "falling", event_id: str | None = None) -> FallEvent:
    return FallEvent(id=event_id or uuid.uuid4().hex, robot="r7", state=state, t_onset=1.0, t_impact=1.4,
                     t_detect=1.5, confidence=0.9, features=("pelvis_velocity",))


def _blocked(tmp_path: Path) -> Path:
    """A state directory that cannot exist: its parent is a regular file (every open fails with ENOTDIR)."""
    (tmp_path / "blocker").write_text("not a folder")
    return tmp_path / "blocker" / "state"


def test_the_journal_keeps_what_it_cannot_store_in_the_fallback_and_takes_it_back(tmp_path):
    fallback = FallbackStore(tmp_path / "run" / "unstored.jsonl")
    state = _blocked(tmp_path)
    journal = EventJournal(state / "events.sqlite3", fallback=fallback)
    first, second = _event(), _event("on_floor")
    journal.append(first)
    journal.append(second)
    journal.mark_published(first.id)
    assert journal.pending_in_memory == 2 and journal.last_error
    kept = [json.loads(line) for line in fallback.path.read_text().splitlines()]
    assert {(k["id"], k["state"]) for k in kept} == {(first.id, "falling"), (second.id, "on_floor")}
    assert [k["published_at"] is not None for k in kept if k["id"] == first.id] == [True]
    assert {e.id for e in journal.unacknowledged()} == {first.id, second.id}    # still republished
    journal.close()

    # the next start, on a state directory that works again: everything goes to the journal, the file goes
    (tmp_path / "blocker").unlink()
    again = EventJournal(state / "events.sqlite3", fallback=fallback)
    assert again.restored == 2 and again.healthy and not fallback.path.exists()
    stored = {(s.event.id, s.event.state): s for s in again.query()}
    assert set(stored) == {(first.id, "falling"), (second.id, "on_floor")}
    assert stored[(first.id, "falling")].published_at is not None
    again.close()
    rows = sqlite3.connect(state / "events.sqlite3").execute("SELECT count(*) FROM messages").fetchone()[0]
    assert rows == 2


def test_an_acknowledged_message_waiting_in_memory_is_acknowledged_in_the_fallback_too(tmp_path):
    fallback = FallbackStore(tmp_path / "unstored.jsonl")
    journal = EventJournal(_blocked(tmp_path) / "events.sqlite3", fallback=fallback)
    e = journal.append(_event())
    assert journal.acknowledge(e.id) == 1
    (kept,) = fallback.load()
    assert kept.acked_at is not None and journal.unacknowledged() == []


def test_a_history_that_cannot_be_opened_keeps_no_rows_and_never_raises(tmp_path):
    path = _blocked(tmp_path) / "history.sqlite3"
    hist = AngleHistory(path)                      # raised before: the publisher crashed, 6 restarts, exit 70
    assert hist.last_error and "history" in hist.last_error
    fake = FitResult.failure(1, 0.0, "x")
    assert hist.add(fake) is False                 # not ok: not kept, as ever
    assert list(hist.rows()) == [] and hist.maintain() == {"deleted": 0, "downsampled": 0}
    hist.close()


def test_private_folder_on_a_file_system_that_refuses_it_does_not_raise(tmp_path):
    private_folder(_blocked(tmp_path))             # OSError before (OSError 30 on a read-only file system)


def test_config_check_flags_a_state_directory_it_cannot_write(tmp_path):
    state = _blocked(tmp_path)
    assert state_dir_problems(state) and "pipeline.state_dir" in state_dir_problems(state)[0]
    assert state_dir_problems(tmp_path / "fine" / "state") == []
    r = subprocess.run([sys.executable, "-m", "posed.cli", "config", "check", "--set",
                        f"pipeline.state_dir={state}"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 78, (r.stdout, r.stderr)
    assert "pipeline.state_dir" in r.stderr and "would start, degraded" in r.stderr


def test_status_text_says_storage_is_degraded():
    status = {"state": "running", "fps": 10.0, "latency_ms": {"p95": 12.0}, "drops": 0, "restarts": 0,
              "camera": {"state": "open", "source": "file:x.mp4", "kind": "file"},
              "storage": {"state": "degraded", "unstored_events": 29, "fallback": "/run/posed/u.jsonl"}}
    text = status_text(status)
    assert "STORAGE DEGRADED" in text and "29 fall-event messages" in text and "/run/posed/u.jsonl" in text
    status["storage"] = {"state": "ok", "unstored_events": 0, "fallback": "/run/posed/u.jsonl"}
    assert "STORAGE" not in status_text(status)


def test_fallback_path_is_per_state_directory_and_under_the_runtime_directory(tmp_path):
    env = {"RUNTIME_DIRECTORY": str(tmp_path / "rt")}
    a, b = fallback_path(tmp_path / "a", env), fallback_path(tmp_path / "b", env)
    assert a != b and a.parent == b.parent == tmp_path / "rt"


@pytest.mark.timeout(180)
def test_the_real_daemon_on_a_state_directory_that_fails_goes_on_and_says_so(tmp_path):
    state = _blocked(tmp_path)
    runtime = tmp_path / "run"

    def daemon(where: Path):
        where.mkdir(parents=True, exist_ok=True)
        return FileHarness(where, f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", f"pipeline.state_dir={state}",
                           "robot_id=r7", "zenoh.event_republish_s=600", *FALL_OVERRIDES,
                           env={"RUNTIME_DIRECTORY": str(runtime)})

    h = daemon(tmp_path / "first")
    try:
        s = h.wait_for(lambda s: s.get("storage", {}).get("unstored_events", 0) >= 1, 90,
                       "a fall event the state directory could not take")
        assert s["storage"]["state"] == "degraded" and s["storage"]["fallback"].startswith(str(runtime))
        assert s["stages"]["publisher"]["alive"] and s["stages"]["publisher"]["restarts"] == 0
    finally:
        code, _, err, _ = h.stop()
    assert code == 0, err
    unstored = s["storage"]["unstored_events"]
    assert "fall-event messages were never written to disk" in err and str(runtime) in err, err
    kept = Path(s["storage"]["fallback"]).read_text().splitlines()
    assert len(kept) >= unstored
    names = [r.get("event") for r in h.log_lines()]
    assert "events_not_stored" in names and names.count("journal_unavailable") <= 2

    # the disk is back: the next start writes them to the journal and removes the fallback file
    (tmp_path / "blocker").unlink()
    h2 = daemon(tmp_path / "second")
    try:
        h2.wait_for(lambda s: s.get("ready") and s.get("storage", {}).get("state") == "ok", 90,
                    "the state directory to work again")
    finally:
        code2, _, err2, _ = h2.stop()
    assert code2 == 0, err2
    ids = {json.loads(line)["id"] for line in kept}
    db = sqlite3.connect(state / "events.sqlite3")
    stored = {r[0] for r in db.execute("SELECT event_id FROM messages")}
    assert ids <= stored and not Path(s["storage"]["fallback"]).exists()


@pytest.mark.timeout(60)
def test_a_read_only_tmpfs_state_directory_is_flagged_by_config_check(tmp_path):
    mnt = tmp_path / "ro"
    mnt.mkdir()
    if shutil.which("mount") is None or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)], capture_output=True).returncode:
        pytest.skip("this machine does not let the test mount a tmpfs (not root)")
    try:
        (mnt / "state").mkdir()
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        problems = state_dir_problems(mnt / "state")
        assert problems and "read-only file system" in problems[0], problems
        private_folder(mnt / "new")                                   # OSError 30 before
        journal = EventJournal(mnt / "state" / "events.sqlite3", fallback=FallbackStore(tmp_path / "u.jsonl"))
        journal.append(_event())
        assert journal.pending_in_memory == 1 and len(FallbackStore(tmp_path / "u.jsonl").load()) == 1
        journal.close()
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)
