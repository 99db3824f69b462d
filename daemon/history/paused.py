"""When posed was paused for privacy: one row per pause, kept in the history file (table ``paused``) beside the
angles and the minutes posed watched (:mod:`daemon.history.watched`).

A person at home asks posed to stop watching for a while (``posed/ROBOT/privacy/pause``); the daemon's keeper
calls :meth:`PauseLog.begin` when a pause starts (and again with the same ``since_unix`` when it is shortened
or extended) and :meth:`PauseLog.end` when it ends: by its time (``"time"``), asked to resume (``"resumed"``)
or with the daemon (``"stopped"``). It is what lets a caregiver's report tell a minute paused for privacy from a
minute posed was not watching for no known reason (``posed report``).

All times are unix seconds. A row is ``(since_unix, until_unix, ended_unix, by, ended, resumed_by)``: when the
pause began, when it was due to end, when it ended (NULL while it runs), who asked (free text or NULL), how it
ended (NULL while it runs) and who asked to resume (NULL unless said).

A daemon killed during a pause leaves its row open: the next writer closes it (at its start and at every
``begin``/``end``) as ``"stopped"`` at the earlier of ``until_unix`` and now. A daemon restarted during a pause
stays paused (the keeper's ``privacy.json``) and calls ``begin`` with the same ``since_unix``: the row it closed
as stopped is opened again, so one pause is one row across a restart.

Like the other history tables this is a record, not an alarm: a write that fails is logged and dropped, never
raised (a history file that cannot be opened is tried again at the next write). Rows expire with the history
(``falls.history_retention_days``; :meth:`daemon.history.store.AngleHistory.maintain` deletes the ``paused``
rows that ended before its cutoff). Readers open it ``readonly``; a history written by a posed older than this
table has no pauses (``between`` returns ``[]``).
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path

ENDED_TIME = "time"          # the pause ran out (until_unix reached)
ENDED_RESUMED = "resumed"    # someone asked posed to watch again (``for=0``)
ENDED_STOPPED = "stopped"    # the daemon stopped (or was killed) during the pause
ENDED = (ENDED_TIME, ENDED_RESUMED, ENDED_STOPPED)

_SCHEMA = ("CREATE TABLE IF NOT EXISTS paused (since_unix REAL NOT NULL, until_unix REAL NOT NULL, "
           "ended_unix REAL, by TEXT, ended TEXT, resumed_by TEXT); "
           "CREATE INDEX IF NOT EXISTS paused_since ON paused (since_unix);")
_COLUMNS = "since_unix, until_unix, ended_unix, by, ended, resumed_by"


@dataclass(frozen=True)
class PauseSpan:
    """One pause, as stored: times in unix seconds; ``ended_unix`` and ``ended`` are None while it runs (or when
    a killed daemon left it open and no writer has closed it yet)."""

    since_unix: float
    until_unix: float
    ended_unix: float | None
    by: str | None
    ended: str | None
    resumed_by: str | None

    def end_unix(self, now: float) -> float:
        """When the pause stopped (unix seconds): ``ended_unix``, or for one still open the earlier of
        ``until_unix`` and ``now`` (unix seconds); never before ``since_unix``."""
        end = self.ended_unix if self.ended_unix is not None else min(self.until_unix, now)
        return max(end, self.since_unix)


class PauseLog:
    """The pauses in ``path`` (the history file, table ``paused``); thread-safe; ``readonly`` for the readers.

    ``clock`` (unix seconds) is what "now" is when a row left open is closed as stopped."""

    def __init__(self, path: str | os.PathLike, log=None, readonly: bool = False, *, clock=time.time) -> None:
        self.path = Path(path)
        self.log = log
        self._clock = clock
        self._lock = threading.Lock()
        self._db: sqlite3.Connection | None = None
        if readonly:
            if not self.path.is_file():
                raise FileNotFoundError(f"no history at {self.path}")
            self._db = sqlite3.connect(f"file:{self.path}?mode=ro", uri=True, check_same_thread=False)
            return
        with self._lock:
            if self._open():
                self._write("paused_write_failed", self._close_stale, None)

    def _open(self) -> bool:
        """Open (create) the file for writing; False (logged) when it cannot be."""
        if self._db is not None:
            return True
        db = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False, timeout=5.0)
            db.execute("PRAGMA journal_mode=WAL")
            db.executescript(_SCHEMA)
        except (sqlite3.Error, OSError) as exc:
            if db is not None:
                db.close()
            self._error("paused_unavailable", exc)
            return False
        self._db = db
        return True

    def _error(self, event: str, exc: BaseException) -> None:
        if self.log is not None:
            self.log.error(event, error=str(exc), path=str(self.path),
                           fix="free disk space or make pipeline.state_dir writable; the report will count this "
                               "pause as time posed was not watching")

    def _write(self, event: str, fn, *args) -> None:
        """Run ``fn(*args)`` in one transaction (the lock held); a failure is logged, never raised."""
        if not self._open():
            return
        try:
            with self._db:
                self._db.execute("BEGIN IMMEDIATE")
                fn(*args)
        except sqlite3.Error as exc:
            self._error(event, exc)

    def _close_stale(self, keep_since: float | None) -> None:
        """Close every open row (but the one that began at ``keep_since``) as stopped at min(until, now)."""
        now = self._clock()
        self._db.execute(
            "UPDATE paused SET ended = ?, ended_unix = MAX(since_unix, MIN(until_unix, ?)) "
            "WHERE ended_unix IS NULL AND (? IS NULL OR since_unix != ?)",
            (ENDED_STOPPED, now, keep_since, keep_since))

    def begin(self, since_unix: float, until_unix: float, by: str | None) -> None:
        """A pause from ``since_unix`` to ``until_unix`` (unix seconds) asked by ``by``: a new row, or, for the
        pause that began at the same ``since_unix`` (open, or closed as stopped by a restart), its ``until_unix``
        and ``by`` updated and the row open again. Any other open row is closed as stopped."""
        since, until = float(since_unix), float(until_unix)

        def run() -> None:
            self._close_stale(since)
            same = self._db.execute(
                "SELECT rowid FROM paused WHERE since_unix = ? AND (ended_unix IS NULL OR ended = ?) "
                "ORDER BY rowid DESC LIMIT 1", (since, ENDED_STOPPED)).fetchone()
            if same is None:
                self._db.execute("INSERT INTO paused (since_unix, until_unix, by) VALUES (?, ?, ?)",
                                 (since, until, by))
            else:
                self._db.execute("UPDATE paused SET until_unix = ?, by = ?, ended_unix = NULL, ended = NULL, "
                                 "resumed_by = NULL WHERE rowid = ?", (until, by, same[0]))

        with self._lock:
            self._write("paused_write_failed", run)

    def end(self, ended_unix: float, ended: str, resumed_by: str | None = None) -> None:
        """Close the open pause at ``ended_unix`` (unix seconds): ``ended`` is ``"time"``, ``"resumed"`` or
        ``"stopped"`` (ValueError otherwise), ``resumed_by`` who asked to resume. Older open rows (left by a
        killed daemon) are closed as stopped; with no open row nothing is written."""
        if ended not in ENDED:
            raise ValueError(f"ended must be one of {', '.join(ENDED)}, not {ended!r}")
        at = float(ended_unix)

        def run() -> None:
            row = self._db.execute("SELECT rowid, since_unix FROM paused WHERE ended_unix IS NULL "
                                   "ORDER BY since_unix DESC, rowid DESC LIMIT 1").fetchone()
            if row is None:
                return
            self._db.execute("UPDATE paused SET ended_unix = MAX(since_unix, ?), ended = ?, resumed_by = ? "
                             "WHERE rowid = ?", (at, ended, resumed_by, row[0]))
            self._close_stale(None)

        with self._lock:
            self._write("paused_write_failed", run)

    def between(self, t0_unix: float, t1_unix: float) -> list[PauseSpan]:
        """The pauses that overlap ``[t0_unix, t1_unix)`` (unix seconds), in time order; an open row counts up to
        its ``until_unix``. ``[]`` from a history without the table (a posed older than pausing)."""
        with self._lock:
            if self._db is None:
                return []
            try:
                rows = self._db.execute(
                    f"SELECT {_COLUMNS} FROM paused WHERE since_unix < ? "
                    "AND COALESCE(ended_unix, until_unix) > ? ORDER BY since_unix, rowid",
                    (float(t1_unix), float(t0_unix))).fetchall()
            except sqlite3.OperationalError as exc:
                if "no such table" in str(exc):
                    return []
                raise
        return [PauseSpan(*row) for row in rows]

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None

    def __enter__(self) -> PauseLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
