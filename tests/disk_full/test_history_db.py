"""The joint-angle history file when it is damaged: the daemon moves it aside and starts a fresh one (and
says why, with the fix that matches), and the reading commands name a file that is not a posed history."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from dataclasses import replace

import pytest

from posed.daemon.history.store import AngleHistory, fix_for
from posed.falls.config import FallsConfig
from posed.fitting import FitResult
from tests.conftest import ROOT
from tests.daemon.zenoh_util import free_port
from tests.disk_full.conftest import posed, short_recording


def _valid_history(path, rows: int = 400) -> None:
    """A history written by the store itself: ``rows`` fits' angles."""
    with AngleHistory(path, FallsConfig(history_rate_hz=1000.0)) as hist:
        for i in range(rows):
            r = FitResult.failure(i, i * 0.01, "x")
            r = replace(r, ok=True, joint_angles_deg={"theta_kn_l": float(i)})
            hist.add(r, wall=1_700_000_000.0 + i)


def test_the_daemon_moves_a_corrupt_history_aside_and_starts_a_fresh_one(tmp_path):
    full = tmp_path / "whole.sqlite3"
    _valid_history(full)
    state = tmp_path / "state"
    state.mkdir(mode=0o700)
    damaged = full.read_bytes()[:8000]          # a file cut short: "database disk image is malformed"
    (state / "history.sqlite3").write_bytes(damaged)
    rec = short_recording(tmp_path / "fall.landmarks.jsonl", 20)
    r = subprocess.run(
        [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{rec}", "--set",
         f"pipeline.state_dir={state}", "--set", "pipeline.stop_at_end=true", "--set", "source.realtime=false",
         "--set", "logging.format=json", "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]"],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    logs = [json.loads(line) for line in (r.stdout + r.stderr).splitlines() if line.startswith("{")]
    assert not [e for e in logs if e.get("event") in ("history_unavailable", "history_write_failed")]
    (warning,) = [e for e in logs if e.get("event") == "history_corrupt"]
    (aside,) = state.glob("history.sqlite3.corrupt-*")
    assert warning["moved_to"] == str(aside) and warning["path"] == str(state / "history.sqlite3")
    assert str(aside) in warning["fix"] and str(state / "history.sqlite3") in warning["fix"]
    assert aside.read_bytes() == damaged         # kept as it was, for a look with sqlite3 .recover
    with AngleHistory(state / "history.sqlite3", readonly=True) as hist:   # a fresh history with today's rows
        assert list(hist.rows())
    assert (state / "history.sqlite3").stat().st_mode & 0o077 == 0


def test_the_fix_matches_the_cause():
    assert "damaged" in fix_for(sqlite3.DatabaseError("database disk image is malformed"))
    assert "damaged" in fix_for(sqlite3.DatabaseError("file is not a database"))
    assert "free disk space" in fix_for(sqlite3.OperationalError("database or disk is full"))
    assert "writable" in fix_for(sqlite3.OperationalError("attempt to write a readonly database"))
    assert "free disk space" not in fix_for(sqlite3.DatabaseError("database disk image is malformed"))


def test_a_full_state_dir_says_to_free_disk_space(tmpfs, caplog):
    mnt = tmpfs("64k")
    (mnt / "filler").write_bytes(b"\0" * (64 * 1024 - 4096))
    hist = AngleHistory(mnt / "history.sqlite3")
    assert hist.last_error
    assert "full" in hist.last_error.lower() or "disk" in hist.last_error.lower()
    hist.close()
    assert not list(mnt.glob("history.sqlite3.corrupt-*"))     # a full disk is not a corrupt file


@pytest.mark.parametrize("command", [("history",), ("plot", "history", "-o", "{tmp}/p.png"),
                                     ("report", "--day", "today", "-o", "{tmp}/r.html")])
@pytest.mark.parametrize("kind", ["text", "no_angles"])
def test_reading_commands_name_a_file_that_is_not_a_posed_history(tmp_path, command, kind):
    db = tmp_path / "bad.sqlite3"
    if kind == "text":
        db.write_text("hello, not a database\n" * 40)
    else:
        con = sqlite3.connect(db)
        con.execute("CREATE TABLE other (a)")
        con.commit()
        con.close()
    args = [a.format(tmp=tmp_path) for a in command]
    r = posed(*args, "--db", str(db))
    # before: sqlite3.DatabaseError: file is not a database / OperationalError: no such table: angles
    assert r.returncode == 2, r.stderr
    assert f"not a posed history database: {db}" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("command", [("history", "--since", "2000-01-01"),
                                     ("plot", "history", "--since", "2000-01-01", "-o", "{tmp}/p.png")])
def test_damage_found_only_while_reading_the_rows_is_named(tmp_path, command):
    """A history that opens (its first page whole) but whose table pages are damaged: one line, exit 2."""
    db = tmp_path / "dmg.sqlite3"
    _valid_history(db, rows=4000)
    raw = bytearray(db.read_bytes())
    page = 4096
    assert len(raw) > 6 * page, len(raw)
    raw[2 * page:6 * page] = b"\xab" * (4 * page)
    db.write_bytes(bytes(raw))
    args = [a.format(tmp=tmp_path) for a in command]
    r = posed(*args, "--db", str(db))
    assert r.returncode == 2, r.stdout + r.stderr
    assert f"cannot read the joint-angle history {db}" in r.stderr and "Traceback" not in r.stderr, r.stderr
