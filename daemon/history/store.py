"""Per-frame joint angles kept for caregivers: SQLite, rate-limited, downsampled when old, deleted when older.

One row per kept frame: wall time (unix seconds; what ``--since/--until`` select on), the capture time ``t``
and ``seq``, and the 23 joint angles plus the body angles (degrees, interfaces.md section 2) — those the frame
measured (``FitResult.measured``, fitting.measured); the rest are NULL, never the model's guess — and the
gravity the fit measured against (``DOWN_COLUMNS``, NULL when it took the camera as level). Rows are
buffered and committed every ``falls.history_commit_every_s`` of capture time (WAL, ``synchronous=NORMAL``: a power loss
may drop the last uncommitted seconds, never corrupts the file — the angles are a record, not an alarm).

``maintain()`` (the publisher calls it about once a minute) averages rows older than
``history_downsample_after_h`` into buckets of ``history_downsample_period_s`` (``level`` 1) and deletes rows older than
``history_retention_days`` (and the pauses for privacy, table ``paused``, that ended before then).

A state directory that cannot take the file (read-only, full, gone) never stops the daemon: the store then
keeps no rows (``last_error`` says why, ``dropped`` counts the rows lost, one log line a minute at most) and
tries to open the file again every ``REOPEN_S``. Fall events do not depend on it (daemon.outbox.journal).
A file that is not a database or is damaged (``database disk image is malformed``) is moved aside to
``history.sqlite3.corrupt-<unix time>`` (with its ``-wal``/``-shm``) and a fresh history started, as the event
journal does; the log line names both paths.

Read-only (``posed history``, ``plot history``, ``report``): a file that is not a posed history (not SQLite,
damaged, or without the ``angles`` table) raises :class:`HistoryFileError` (a ValueError) naming the path.
"""

from __future__ import annotations

import csv
import io
import math
import os
import sqlite3
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

from posed.daemon import logs
from posed.daemon.clock import iso
from posed.daemon.outbox.journal_file import is_corrupt, set_aside  # the same SQLite files' rules
from posed.daemon.outbox.journal_rows import table_columns
from posed.falls.config import FallsConfig
from posed.fitting import BODY_ANGLE_NAMES, JOINT_ANGLE_NAMES, FitResult

ANGLE_COLUMNS = JOINT_ANGLE_NAMES + BODY_ANGLE_NAMES
# the direction of gravity the fit measured the body angles against (its result's ``down``, camera axes, unit;
# fitting.vertical), NULL when it took the camera as level: what the day's postures are measured against
DOWN_COLUMNS = ("down_x", "down_y", "down_z")
ROW_COLUMNS = ANGLE_COLUMNS + DOWN_COLUMNS
CSV_HEADER = ("wall_time", "wall", "t", "seq", "level", *ROW_COLUMNS)

_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS angles (wall REAL NOT NULL, t REAL NOT NULL, seq INTEGER NOT NULL, "
    "level INTEGER NOT NULL DEFAULT 0, "
    + ", ".join(f"{name} REAL" for name in ROW_COLUMNS)
    + "); CREATE INDEX IF NOT EXISTS angles_wall ON angles (wall);"
)


class HistoryFileError(ValueError):
    """A history file a reader cannot use: not SQLite, damaged, or not a posed history (no ``angles``)."""


REOPEN_S = 30.0          # a history file that could not be opened is tried again this often (monotonic s)
LOG_EVERY_S = 60.0       # while the same trouble lasts, one log line a minute


class AngleHistory:
    """Joint-angle history in one SQLite file; ``add`` is cheap (rate limit + buffer), thread-safe."""

    def __init__(self, path: str | os.PathLike, cfg: FallsConfig | None = None, clock=time.time,
                 readonly: bool = False) -> None:
        self.path = Path(path)
        self.cfg = cfg or FallsConfig()
        self._clock = clock
        self._lock = threading.Lock()
        self._buffer: list[tuple] = []
        self._last_kept_t: float | None = None
        self._last_commit_t: float | None = None
        self._log = logs.get("history", path=str(self.path))
        self._db: sqlite3.Connection | None = None
        self._columns: set[str] = set(ROW_COLUMNS)   # the file's columns (a history from before DOWN_COLUMNS lacks them)
        self.last_error = ""
        self.dropped = 0
        self._next_open = 0.0
        self._next_log = 0.0
        self._readonly = readonly
        if readonly:
            if not self.path.is_file():
                raise FileNotFoundError(f"no joint-angle history at {self.path}: the daemon writes it while it "
                                        "runs (falls.history_enabled); check pipeline.state_dir")
            self._db = _open_readonly(self.path)
            self._columns = table_columns(self._db, "angles")
        else:
            self._open()

    def _open(self, aside_done: bool = False) -> None:
        """Open (create) the file for writing; a corrupt file is moved aside and a fresh one started; on any
        other failure ``last_error`` is set and the store keeps no rows."""
        self._next_open = time.monotonic() + REOPEN_S
        db = None
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False, timeout=5.0)
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=NORMAL")
            db.executescript(_SCHEMA)
            have = table_columns(db, "angles")
            for name in DOWN_COLUMNS:          # a history written before them: the columns added, old rows NULL
                if name not in have:
                    db.execute(f"ALTER TABLE angles ADD COLUMN {name} REAL")
            self._columns = table_columns(db, "angles")
        except (sqlite3.Error, OSError) as exc:
            if db is not None:
                db.close()
            if isinstance(exc, sqlite3.DatabaseError) and is_corrupt(exc) and not aside_done:
                self._set_aside(exc)
                return
            self._trouble("history_unavailable", f"cannot open the joint-angle history {self.path}: {exc}",
                          exc)
            return
        self._db = db
        if self.last_error:
            self._log.info("history_recovered", previous_error=self.last_error, dropped=self.dropped)
            self.last_error = ""

    def _set_aside(self, exc: sqlite3.DatabaseError) -> None:
        """Move a corrupt history file (and its WAL and shared-memory files) aside, as the event journal's is
        (``journal_file.set_aside``), then start a fresh one."""
        aside = set_aside(self.path, time.time())
        if self.path.exists():           # the rename failed (set_aside skips what it cannot move)
            self._trouble("history_unavailable", f"the joint-angle history {self.path} is damaged ({exc}) and "
                          f"cannot be moved aside to {aside}", exc)
            return
        try:      # health data: the fresh file is private (0600) like the one it replaces (daemon.outbox.private)
            os.close(os.open(self.path, os.O_WRONLY | os.O_CREAT, 0o600))
        except OSError:
            pass      # the open below reports what is wrong with the folder or the disk
        self._log.warning("history_corrupt", error=str(exc), path=str(self.path), moved_to=str(aside),
                          fix=f"the damaged history was moved to {aside} and a new one started at {self.path}; "
                              f"the rows before are in the old file (sqlite3 {aside} .recover) or lost")
        self._open(aside_done=True)

    def _trouble(self, event: str, message: str, exc: BaseException | None = None, **kw) -> None:
        now = time.monotonic()
        if not self.last_error or now >= self._next_log:
            self._next_log = now + LOG_EVERY_S
            self._log.error(event, error=message, dropped=self.dropped, fix=fix_for(exc) + "; the joint-angle "
                            "history misses these rows (fall events are journalled separately)", **kw)
        self.last_error = message

    def add(self, result: FitResult, wall: float | None = None) -> bool:
        """Keep this frame's angles if the rate allows (capture time decides); True when kept."""
        if not result.ok or not result.joint_angles_deg:
            return False
        with self._lock:
            period = 1.0 / self.cfg.history_rate_hz
            if self._last_kept_t is not None and result.t < self._last_kept_t + period - 1e-6 \
                    and result.t >= self._last_kept_t:
                return False
            self._last_kept_t = result.t
            measured = result.measured_angles()   # fitting.measured: an angle this frame did not see is NULL
            values = [_num(measured.get(n)) for n in ANGLE_COLUMNS]
            down = _down(result.extra.get("down"))
            self._buffer.append((self._clock() if wall is None else wall, result.t, result.seq, 0, *values, *down))
            if self._last_commit_t is None:
                self._last_commit_t = result.t
            if abs(result.t - self._last_commit_t) >= self.cfg.history_commit_every_s:
                self._commit()
            return True

    def flush(self) -> None:
        """Write the buffered rows now."""
        with self._lock:
            self._commit()

    def _commit(self) -> None:
        if not self._buffer:
            return
        if self._db is None and time.monotonic() >= self._next_open:
            self._open()
        if self._db is None:
            self.dropped += len(self._buffer)
            self._buffer.clear()
            self._last_commit_t = self._last_kept_t
            return
        try:
            self._insert_buffer()
            if self.last_error:
                self._log.info("history_recovered", previous_error=self.last_error, dropped=self.dropped)
                self.last_error = ""
        except sqlite3.Error as exc:
            if isinstance(exc, sqlite3.DatabaseError) and is_corrupt(exc):   # damaged since it was opened
                self._db.close()
                self._db = None
                self._set_aside(exc)
                if self._db is not None:
                    try:
                        self._insert_buffer()
                        self._buffer.clear()
                        self._last_commit_t = self._last_kept_t
                        return
                    except sqlite3.Error as exc2:
                        exc = exc2
            self.dropped += len(self._buffer)
            self._trouble("history_write_failed", f"cannot write the joint-angle history {self.path}: {exc}",
                          exc)
        self._buffer.clear()
        self._last_commit_t = self._last_kept_t

    def _insert_buffer(self) -> None:
        """The buffered rows in one transaction (sqlite3.Error when it fails)."""
        marks = ", ".join("?" * len(CSV_HEADER[1:]))
        with self._db:
            self._db.execute("BEGIN")
            self._db.executemany(f"INSERT INTO angles (wall, t, seq, level, {', '.join(ROW_COLUMNS)}) "
                                 f"VALUES ({marks})", self._buffer)

    def maintain(self, now: float | None = None) -> dict:
        """Downsample old rows and delete expired ones; returns counts."""
        now = self._clock() if now is None else now
        with self._lock:
            self._commit()
            if self._db is None:
                return {"deleted": 0, "downsampled": 0}
            cutoff_old = now - self.cfg.history_downsample_after_h * 3600.0
            cutoff_gone = now - self.cfg.history_retention_days * 86400.0
            bucket = self.cfg.history_downsample_period_s
            avg = ", ".join(f"AVG({n})" for n in ROW_COLUMNS)
            try:
                with self._db:
                    self._db.execute("BEGIN")
                    deleted = self._db.execute("DELETE FROM angles WHERE wall < ?", (cutoff_gone,)).rowcount
                    if self._db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'paused'"
                                        ).fetchone():   # the pauses for privacy (daemon.history.paused) expire too
                        self._db.execute("DELETE FROM paused WHERE COALESCE(ended_unix, until_unix) < ?",
                                         (cutoff_gone,))
                    before = self._db.execute("SELECT count(*) FROM angles WHERE level = 0 AND wall < ?",
                                              (cutoff_old,)).fetchone()[0]
                    if before:
                        self._db.execute(
                            f"INSERT INTO angles (wall, t, seq, level, {', '.join(ROW_COLUMNS)}) "
                            f"SELECT MIN(wall), MIN(t), MIN(seq), 1, {avg} FROM angles "
                            "WHERE level = 0 AND wall < ? GROUP BY CAST(wall / ? AS INTEGER)",
                            (cutoff_old, bucket))
                        self._db.execute("DELETE FROM angles WHERE level = 0 AND wall < ?", (cutoff_old,))
                    after = self._db.execute("SELECT count(*) FROM angles WHERE level = 1 AND wall < ?",
                                             (cutoff_old,)).fetchone()[0]
            except sqlite3.Error as exc:
                self._log.error("history_maintenance_failed", error=str(exc),
                                fix="check disk space and pipeline.state_dir")
                return {"deleted": 0, "downsampled": 0}
        return {"deleted": deleted, "downsampled": before, "old_rows": after}

    def rows(self, since: float | None = None, until: float | None = None,
             columns: Iterable[str] = ANGLE_COLUMNS) -> Iterator[tuple]:
        """(wall, t, seq, level, *columns) rows in time order, between two unix times (inclusive); ``columns``
        of ROW_COLUMNS (a column the file does not have, from before it was added, reads NULL)."""
        columns = tuple(columns)
        bad = [c for c in columns if c not in ROW_COLUMNS]
        if bad:
            raise ValueError(f"unknown angle(s) {', '.join(bad)}; known: {', '.join(ROW_COLUMNS)}")
        with self._lock:
            self._commit()
            if self._db is None:
                return
            picked = (c if c in self._columns else "NULL" for c in columns)
            sql = f"SELECT wall, t, seq, level{''.join(', ' + c for c in picked)} FROM angles WHERE 1"
            args: list[float] = []
            if since is not None:
                sql += " AND wall >= ?"
                args.append(since)
            if until is not None:
                sql += " AND wall <= ?"
                args.append(until)
            try:
                rows = self._db.execute(sql + " ORDER BY wall, t", args).fetchall()
            except sqlite3.DatabaseError as exc:
                if not self._readonly:
                    raise
                raise HistoryFileError(f"cannot read the joint-angle history {self.path}: {exc}") from None
        yield from rows

    def export_csv(self, out: io.TextIOBase, since: float | None = None, until: float | None = None) -> int:
        """Write CSV (header ``CSV_HEADER``; empty cell = unknown); returns the number of rows."""
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(CSV_HEADER)
        n = 0
        for wall, t, seq, level, *values in self.rows(since, until, ROW_COLUMNS):
            writer.writerow([iso(wall), repr(wall),
                             repr(t), seq, level, *("" if v is None else repr(v) for v in values)])
            n += 1
        return n

    def close(self) -> None:
        with self._lock:
            try:
                self._commit()
            except sqlite3.Error:
                pass
            if self._db is not None:
                self._db.close()
                self._db = None

    def __enter__(self) -> AngleHistory:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_csv(text: str) -> list[dict]:
    """Parse an exported CSV back into dicts of floats (None for empty cells); the inverse of export_csv."""
    out = []
    for row in csv.DictReader(io.StringIO(text)):
        rec: dict = {"wall_time": row["wall_time"], "wall": float(row["wall"]), "t": float(row["t"]),
                     "seq": int(row["seq"]), "level": int(row["level"])}
        for name in ROW_COLUMNS:            # a file exported before DOWN_COLUMNS lacks them: None
            rec[name] = float(row[name]) if row.get(name) not in (None, "") else None
        out.append(rec)
    return out


def fix_for(exc: BaseException | None) -> str:
    """What to do about a failure to open or write the history, by its cause."""
    text = str(exc).lower()
    if isinstance(exc, sqlite3.DatabaseError) and is_corrupt(exc):
        return "the history file is damaged; move it aside (or delete it) so that a new one is started"
    if "full" in text or getattr(exc, "errno", None) == 28:
        return "free disk space on pipeline.state_dir's file system"
    if "readonly" in text or "read-only" in text or "permission" in text or isinstance(exc, PermissionError):
        return "make pipeline.state_dir writable by the daemon's user"
    return "check pipeline.state_dir (free disk space, make it writable)"


def _open_readonly(path: Path) -> sqlite3.Connection:
    """The history file opened read-only, checked to be a posed history; HistoryFileError naming the path
    when it is not (not SQLite, damaged, no ``angles`` table)."""
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, check_same_thread=False)
    try:
        found = db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'angles'").fetchone()
    except sqlite3.DatabaseError as exc:
        db.close()
        raise HistoryFileError(f"not a posed history database: {path} ({exc}); give the daemon's "
                               "history.sqlite3 (--db FILE or pipeline.state_dir)") from None
    if found is None:
        db.close()
        raise HistoryFileError(f"not a posed history database: {path} (it has no joint-angle table); give the "
                               "daemon's history.sqlite3 (--db FILE or pipeline.state_dir)")
    return db


def _down(v) -> tuple:
    """A result's ``down`` as three finite numbers, or three NULLs (none, or not three finite numbers)."""
    try:
        d = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        return (None, None, None)
    return d if len(d) == 3 and all(math.isfinite(x) for x in d) else (None, None, None)


def _num(v) -> float | None:
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None
