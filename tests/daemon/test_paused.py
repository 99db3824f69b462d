"""The pauses for privacy in the history file (daemon.history.paused): what PauseLog keeps, in real SQLite,
against a plain reference of the contract's rules (a new pause is a new row; the same ``since_unix`` updates the
open row, or opens again the one a restart closed as stopped; ``end`` closes the open row; rows a killed daemon
left open are closed as stopped at min(until, now)); a daemon killed during a pause; a write that fails is logged,
never raised; readers of an older history see no pauses; rows expire with the history."""

from __future__ import annotations

import os
import random
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from posed.daemon.history.paused import ENDED, PauseLog, PauseSpan
from posed.daemon.history.store import AngleHistory
from posed.falls.config import FallsConfig


class Log:
    def __init__(self) -> None:
        self.errors: list[tuple[str, dict]] = []

    def error(self, event, **kw) -> None:
        self.errors.append((event, kw))


class Reference:
    """The contract's rules, restated plainly over a list of rows (dicts), in insertion order."""

    def __init__(self) -> None:
        self.rows: list[dict] = []

    def close_stale(self, now: float, keep_since: float | None = None) -> None:
        for r in self.rows:
            if r["ended_unix"] is None and r["since_unix"] != keep_since:
                r["ended_unix"] = max(r["since_unix"], min(r["until_unix"], now))
                r["ended"] = "stopped"

    def begin(self, since: float, until: float, by, now: float) -> None:
        self.close_stale(now, keep_since=since)
        same = [r for r in self.rows if r["since_unix"] == since and r["ended"] in (None, "stopped")]
        if same:
            same[-1].update(until_unix=until, by=by, ended_unix=None, ended=None, resumed_by=None)
        else:
            self.rows.append(dict(since_unix=since, until_unix=until, ended_unix=None, by=by, ended=None,
                                  resumed_by=None))

    def end(self, at: float, ended: str, resumed_by, now: float) -> None:
        open_rows = [(r["since_unix"], i) for i, r in enumerate(self.rows) if r["ended_unix"] is None]
        if not open_rows:
            return
        r = self.rows[max(open_rows)[1]]
        r.update(ended_unix=max(r["since_unix"], at), ended=ended, resumed_by=resumed_by)
        self.close_stale(now)

    def between(self, t0: float, t1: float) -> list[PauseSpan]:
        hits = [(r["since_unix"], i, r) for i, r in enumerate(self.rows)
                if r["since_unix"] < t1 and (r["until_unix"] if r["ended_unix"] is None else r["ended_unix"]) > t0]
        return [PauseSpan(**r) for _, _, r in sorted(hits, key=lambda h: h[:2])]


@pytest.mark.parametrize("seed", range(6))
def test_the_log_keeps_what_the_reference_says(tmp_path, seed):
    """Random begins, extensions, ends and restarts (a PauseLog opened again: a daemon killed and started),
    on a coarse time grid so that pauses share start times; every reading matches the reference."""
    rng = random.Random(seed)
    path = tmp_path / "history.sqlite3"
    now = [1_765_000_000.0]
    log = PauseLog(path, clock=lambda: now[0])
    ref = Reference()
    since = None
    for _ in range(120):
        now[0] += rng.choice((0.0, 30.0, 60.0, 600.0))
        op = rng.random()
        if op < 0.35:              # a new pause, or the running one changed (same since_unix)
            if since is None or rng.random() < 0.4:
                since = now[0]
            until = now[0] + rng.choice((0.0, 60.0, 900.0, 3600.0))
            by = rng.choice((None, "voice", "app", "Anna"))
            log.begin(since, until, by)
            ref.begin(since, until, by, now[0])
        elif op < 0.65:
            ended = rng.choice(ENDED)
            rb = rng.choice((None, "voice")) if ended == "resumed" else None
            log.end(now[0], ended, rb)
            ref.end(now[0], ended, rb, now[0])
            since = None if rng.random() < 0.7 else since
        elif op < 0.8:             # the daemon restarted (killed: nothing closed it)
            log.close()
            log = PauseLog(path, clock=lambda: now[0])
            ref.close_stale(now[0])
        t0 = rng.uniform(now[0] - 4000.0, now[0])
        t1 = t0 + rng.choice((1.0, 600.0, 86400.0))
        assert log.between(t0, t1) == ref.between(t0, t1)
    log.close()
    with PauseLog(path, readonly=True) as r:
        assert r.between(0, 2e9) == ref.between(0, 2e9)
    assert len(ref.rows) > 5 and {r["ended"] for r in ref.rows} >= {"time", "resumed", "stopped"}


def test_a_restart_during_a_pause_keeps_one_row(tmp_path):
    """A daemon restarted during a pause closes the row as stopped, then (still paused) begins again with the
    same since_unix: one row, open again; ended by its time later."""
    path = tmp_path / "history.sqlite3"
    with PauseLog(path, clock=lambda: 1000.0) as log:
        log.begin(900.0, 1800.0, "voice")
    log = PauseLog(path, clock=lambda: 1100.0)
    assert log.between(0, 1e4) == [PauseSpan(900.0, 1800.0, 1100.0, "voice", "stopped", None)]
    log.begin(900.0, 1800.0, "voice")
    log.end(1800.0, "time")
    assert log.between(0, 1e4) == [PauseSpan(900.0, 1800.0, 1800.0, "voice", "time", None)]
    log.close()


_KILLED = """
import sys, time
from posed.daemon.history.paused import PauseLog
log = PauseLog(sys.argv[1])
log.begin(float(sys.argv[2]), float(sys.argv[3]), "voice")
print("paused", flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("until_in_s", [-120.0, 3600.0])
def test_a_pause_left_open_by_a_killed_daemon_is_closed_as_stopped(tmp_path, until_in_s):
    """A process that began a pause is killed (SIGKILL); the next writer closes its row as stopped at the
    earlier of its until_unix and now."""
    path = tmp_path / "history.sqlite3"
    since = time.time() - 600.0
    until = time.time() + until_in_s
    proc = subprocess.Popen([sys.executable, "-c", _KILLED, str(path), repr(since), repr(until)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "paused"
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    with PauseLog(path, readonly=True) as r:
        assert [s.ended for s in r.between(0, 2e9)] == [None]          # the reader does not close it
    before = time.time()
    with PauseLog(path) as log:
        after = time.time()
        (span,) = log.between(0, 2e9)
    assert (span.since_unix, span.until_unix, span.by, span.ended) == (since, until, "voice", "stopped")
    if until < before:
        assert span.ended_unix == until
    else:
        assert before <= span.ended_unix <= after


def test_a_failed_write_is_logged_not_raised(tmp_path):
    path = tmp_path / "history.sqlite3"
    log = Log()
    w = PauseLog(path, log)
    other = sqlite3.connect(path)
    other.execute("DROP TABLE paused")                 # the file lost its table under the daemon
    other.close()
    w.begin(1000.0, 2000.0, "voice")
    w.end(1500.0, "resumed")
    assert [e for e, _ in log.errors] == ["paused_write_failed"] * 2 and all("fix" in kw for _, kw in log.errors)
    w.close()


def test_a_history_that_cannot_be_opened_is_logged_not_raised(tmp_path):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    log = Log()
    w = PauseLog(blocker / "history.sqlite3", log)     # its folder cannot be made
    w.begin(1000.0, 2000.0, None)
    assert w.between(0, 1e4) == [] and {e for e, _ in log.errors} == {"paused_unavailable"}
    w.close()


def test_an_older_history_has_no_pauses(tmp_path):
    path = tmp_path / "old.sqlite3"
    sqlite3.connect(path).execute("CREATE TABLE angles (wall REAL)").connection.close()
    with PauseLog(path, readonly=True) as r:
        assert r.between(0, 1e10) == []
    with pytest.raises(FileNotFoundError):
        PauseLog(tmp_path / "none.sqlite3", readonly=True)


def test_end_says_how(tmp_path):
    with PauseLog(tmp_path / "h.sqlite3") as w, pytest.raises(ValueError, match="time, resumed, stopped"):
        w.end(1.0, "done")


def test_pauses_expire_with_the_history(tmp_path):
    """The store's maintenance deletes the pauses that ended before the retention cutoff, as it does the angles
    (daemon.history.store); a pause still inside it is kept."""
    path = tmp_path / "history.sqlite3"
    cfg = FallsConfig(history_retention_days=2.0)
    now = 1_765_000_000.0
    store = AngleHistory(path, cfg, clock=lambda: now)
    with PauseLog(path, clock=lambda: now) as log:
        for days_ago in (5.0, 2.5, 1.0):
            since = now - days_ago * 86400.0
            log.begin(since, since + 1800.0, "voice")
            log.end(since + 900.0, "resumed", "voice")
        store.maintain(now)
        kept = log.between(0, 2e9)
    store.close()
    assert [round((now - s.since_unix) / 86400.0, 3) for s in kept] == [1.0]
