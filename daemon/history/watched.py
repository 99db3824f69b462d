"""When posed was watching: one row per minute in which frames came through the pipeline, kept in the history
file (table ``watched``) beside the joint angles: how many frames, how many with a person in view, how many
fitted, and the seconds watched and with a person in view (each frame counts the time since the one before,
at most ``MAX_FRAME_GAP_S``). A minute without a row is a minute posed saw nothing: the daemon off, or no
frames from the camera.

It is what lets a caregiver's report (``posed report``) tell "no fall while posed was watching" from "posed
was not watching" (the angle history alone has rows only while a person is fitted). Counts are kept in memory
and written (added to the minute's row) on ``flush``, which the recorder calls as often as it writes the angle
rows (``falls.history_commit_every_s``) and at shutdown; a failed write is logged and the counts are dropped, never raised (like the angles, a record, not an
alarm). Rows expire with the history (``history_retention_days``).
"""

from __future__ import annotations

import os
import sqlite3
import threading
from pathlib import Path

MINUTE_S = 60
MAX_FRAME_GAP_S = 2.0   # a frame counts the time since the one before, at most this (a gap is not watching)
_SCHEMA = ("CREATE TABLE IF NOT EXISTS watched (minute INTEGER PRIMARY KEY, frames INTEGER NOT NULL, "
           "person INTEGER NOT NULL, fitted INTEGER NOT NULL, watched_s REAL NOT NULL, person_s REAL NOT NULL)")
_COLUMNS = ("frames", "person", "fitted", "watched_s", "person_s")


def frame_seconds(last: float | None, wall: float) -> float:
    """The seconds a frame at unix time ``wall`` counts as watched: the time since the frame before (``last``;
    0 for the first), at most ``MAX_FRAME_GAP_S`` (a longer gap is not watching), never negative."""
    return 0.0 if last is None else min(max(wall - last, 0.0), MAX_FRAME_GAP_S)


class WatchLog:
    """Per-minute frame counts in ``path`` (the history file); thread-safe; ``readonly`` for the readers."""

    def __init__(self, path: str | os.PathLike, log=None, readonly: bool = False) -> None:
        self.path = Path(path)
        self.log = log
        self._lock = threading.Lock()
        self._counts: dict[int, list[float]] = {}
        self._last: float | None = None
        if readonly:
            if not self.path.is_file():
                raise FileNotFoundError(f"no history at {self.path}")
            self._db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True, check_same_thread=False)
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False, timeout=5.0)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute(_SCHEMA)

    def add(self, wall: float, person: bool, fitted: bool) -> None:
        """One frame at unix time ``wall``: whether a person was in view and whether the fit succeeded."""
        minute = int(wall // MINUTE_S) * MINUTE_S
        with self._lock:
            dt = frame_seconds(self._last, wall)
            self._last = wall
            c = self._counts.setdefault(minute, [0, 0, 0, 0.0, 0.0])
            c[0] += 1
            c[1] += bool(person)
            c[2] += bool(fitted)
            c[3] += dt
            c[4] += dt if person else 0.0

    def flush(self) -> None:
        """Add the counts so far to their minutes' rows."""
        with self._lock:
            counts, self._counts = self._counts, {}
        if not counts:
            return
        try:
            with self._db:
                self._db.execute("BEGIN")
                self._db.executemany(
                    f"INSERT INTO watched (minute, {', '.join(_COLUMNS)}) VALUES (?, ?, ?, ?, ?, ?) "
                    "ON CONFLICT(minute) DO UPDATE SET "
                    + ", ".join(f"{c} = {c} + excluded.{c}" for c in _COLUMNS),
                    [(m, *c) for m, c in sorted(counts.items())])
        except sqlite3.Error as exc:
            if self.log is not None:
                self.log.error("watched_write_failed", error=str(exc), minutes=len(counts),
                               fix="free disk space or make pipeline.state_dir writable; the report will count "
                                   "these minutes as not watched")

    def expire(self, before: float) -> None:
        """Delete the minutes before unix time ``before``."""
        try:
            with self._db:
                self._db.execute("DELETE FROM watched WHERE minute < ?", (before,))
        except sqlite3.Error as exc:
            if self.log is not None:
                self.log.error("watched_expire_failed", error=str(exc))

    def minutes(self, since: float, until: float) -> list[tuple[int, int, int, int, float, float]] | None:
        """(minute start in unix seconds, frames, with a person, fitted, seconds watched, seconds with a
        person) of the minutes from ``since`` to ``until``, in time order; None when this history file has no
        such record (written by a posed older than it: when it watched cannot be told)."""
        return self._read(f"SELECT minute, {', '.join(_COLUMNS)} FROM watched WHERE minute >= ? AND minute < ? "
                          "ORDER BY minute", (int(since // MINUTE_S) * MINUTE_S, until))

    def last_minute_seen(self, person_s: float, before: float) -> float | None:
        """The start (unix seconds) of the last minute before ``before`` with at least ``person_s`` seconds of a
        person in view; None when none (or no such record)."""
        row = self._read("SELECT MAX(minute) FROM watched WHERE person_s >= ? AND minute < ?", (person_s, before))
        return None if not row or row[0][0] is None else float(row[0][0])

    def watched_seconds(self, since: float, until: float) -> float:
        """The seconds watched in the minutes from ``since`` to ``until`` (0 when none, or no such record)."""
        row = self._read("SELECT SUM(MAX(watched_s, 0)) FROM watched WHERE minute >= ? AND minute < ?",
                         (since, until))
        return float(row[0][0] or 0.0) if row else 0.0

    def _read(self, sql: str, args: tuple) -> list[tuple] | None:
        with self._lock:
            try:
                return self._db.execute(sql, args).fetchall()
            except sqlite3.OperationalError as exc:
                if "no such table" in str(exc):
                    return None
                raise

    def close(self) -> None:
        self.flush()
        self._db.close()

    def __enter__(self) -> WatchLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
