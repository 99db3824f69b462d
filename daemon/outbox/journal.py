"""The fall-event journal: every event message is on disk before it is published, and kept until acknowledged.

One SQLite file (``events.sqlite3`` in the state dir), WAL mode, ``synchronous=FULL``: each commit fsyncs the
write-ahead log, so a message whose ``append`` returned survives a kill -9 or a power loss. A message is one
state of one event (``falling``, ``on_floor``, ``alarm``, ``recovered``); updates keep the event's ``id``.

Life of a message: ``append`` (stored, unpublished) -> ``mark_published`` -> ``acknowledge`` (a receiver
confirmed it). ``unacknowledged()`` is what the publisher republishes after a restart or a reconnect.

When the disk is full, the file is not writable or the database is corrupt, the journal says so in one clear
log line, keeps the messages in memory (they are still returned by ``unacknowledged`` and ``query``) and
writes them on the next call, or on ``retry()``. A corrupt file is moved aside (``*.corrupt-<unix time>``)
after salvaging the unacknowledged rows that can still be read, and a fresh journal is started.

``EventJournal(path, readonly=True)`` is for readers other than the daemon (``posed events``, ``posed plot``):
it opens the file read-only, creates nothing, never moves a file aside and never logs; a file it cannot read
raises ``JournalError`` naming the file and the fix.
"""

from __future__ import annotations

import json
import os
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from daemon import logs
from daemon.clock import iso
from falls.event import FallEvent

_SCHEMA = """
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


@dataclass(frozen=True)
class StoredEvent:
    """One journalled message and its delivery state (times are unix seconds)."""

    event: FallEvent
    wall: float
    published_at: float | None
    acked_at: float | None

    def to_json(self) -> dict:
        out = self.event.to_json()
        out["published_at"] = self.published_at
        out["acked_at"] = self.acked_at
        return out


class JournalError(RuntimeError):
    """The journal cannot be used at all (raised by ``EventJournal(path, strict=True)`` and by a read-only
    journal that cannot read its file)."""


class EventJournal:
    """SQLite journal of fall-event messages; thread-safe (the publisher and Zenoh callbacks share it)."""

    def __init__(self, path: str | os.PathLike, strict: bool = False, clock=time.time,
                 connect: Callable[[Path], sqlite3.Connection] | None = None, readonly: bool = False) -> None:
        """``connect`` opens the file (default: ``sqlite3.connect`` with a 5 s busy timeout); tests pass one
        that limits the file's size to meet a real SQLITE_FULL.

        ``readonly``: only read an existing journal (raises FileNotFoundError when there is none, JournalError
        when it cannot be read); the writing methods then raise JournalError.
        """
        self.path = Path(path)
        self._readonly = readonly
        self._clock = clock
        self._connect = connect or _default_connect
        self._lock = threading.RLock()
        self._db: sqlite3.Connection | None = None
        # (event_id, state) -> StoredEvent not yet on disk, plus delivery updates not yet on disk
        self._pending: dict[tuple[str, str], StoredEvent] = {}
        self._pending_marks: list[tuple[str, str | None, str, float]] = []
        self.last_error: str = ""
        self._log = logs.get("journal", path=str(self.path))
        if readonly:
            self._db = _open_readonly(self.path)
            return
        with self._lock:
            self._open()
        if strict and self._db is None:
            raise JournalError(self.last_error)

    # ---------------------------------------------------------------- opening and failures

    def _open(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            db = self._connect(self.path)
            try:
                _prepare(db)
                db.execute("SELECT count(*) FROM messages").fetchone()
            except sqlite3.DatabaseError:
                db.close()
                raise
        except sqlite3.DatabaseError as exc:
            if _is_corrupt(exc):
                self._set_aside_corrupt(exc)
                return
            self._fail("cannot open the event journal", exc)
            return
        except OSError as exc:
            self._fail("cannot create the event journal's folder", exc)
            return
        self._db = db
        if self.last_error:
            self._log.info("journal_recovered", previous_error=self.last_error)
            self.last_error = ""

    def _set_aside_corrupt(self, exc: Exception) -> None:
        salvaged = self._salvage()
        aside = self.path.with_name(f"{self.path.name}.corrupt-{int(self._clock())}")
        for suffix in ("", "-wal", "-shm"):
            src = Path(str(self.path) + suffix)
            if src.exists():
                try:
                    src.rename(Path(str(aside) + suffix))
                except OSError:
                    pass
        self._log.error("journal_corrupt", error=str(exc), moved_to=str(aside), salvaged=len(salvaged),
                        fix="the corrupt file was moved aside and a new journal started; inspect or delete "
                            f"{aside} (sqlite3 {aside} .recover)")
        for item in salvaged:
            self._pending.setdefault((item.event.id, item.event.state), item)
        self._db = None
        try:
            db = self._connect(self.path)
            _prepare(db)
            self._db = db
            self.last_error = ""
        except (sqlite3.DatabaseError, OSError) as exc2:
            self._fail("cannot create a fresh event journal after setting the corrupt one aside", exc2)
            return
        self._flush()

    def _salvage(self) -> list[StoredEvent]:
        out: list[StoredEvent] = []
        try:
            db = sqlite3.connect(_readonly_uri(self.path), uri=True, timeout=1.0)
            try:
                rows = db.execute("SELECT body, wall, published_at, acked_at FROM messages "
                                  "WHERE acked_at IS NULL").fetchall()
            finally:
                db.close()
        except sqlite3.DatabaseError:
            return out
        for body, wall, pub, ack in rows:
            try:
                out.append(StoredEvent(FallEvent.from_json(json.loads(body)), wall, pub, ack))
            except (ValueError, KeyError, TypeError):
                continue
        return out

    def _fail(self, what: str, exc: BaseException) -> None:
        message = f"{what} {self.path}: {exc}"
        hint = _hint(exc)
        if message != self.last_error:
            self._log.error("journal_unavailable", error=message, fix=hint,
                            kept_in_memory=len(self._pending))
        self.last_error = message
        self._close_db()

    def _close_db(self) -> None:
        if self._db is not None:
            try:
                self._db.close()
            except sqlite3.Error:
                pass
        self._db = None

    def _check_writable(self) -> None:
        if self._readonly:
            raise JournalError(f"the event journal {self.path} was opened read-only")

    @property
    def healthy(self) -> bool:
        """True when the file is open and nothing waits in memory."""
        with self._lock:
            return self._db is not None and not self._pending and not self._pending_marks

    @property
    def pending_in_memory(self) -> int:
        with self._lock:
            return len(self._pending)

    def retry(self) -> bool:
        """Try again to open the file and write what waits in memory; True when everything is on disk."""
        self._check_writable()
        with self._lock:
            if self._db is None:
                self._open()
            if self._db is not None:
                self._flush()
            return self._db is not None and not self._pending and not self._pending_marks

    def _flush(self) -> None:
        if self._db is None:
            return
        try:
            with _transaction(self._db):
                for item in self._pending.values():
                    self._insert(item)
                for event_id, state, column, when in self._pending_marks:
                    self._mark(event_id, state, column, when)
        except (sqlite3.DatabaseError, OSError) as exc:
            self._fail("cannot write to the event journal", exc)
            return
        self._pending.clear()
        self._pending_marks.clear()

    def _insert(self, item: StoredEvent) -> None:
        e = item.event
        assert self._db is not None
        self._db.execute(
            "INSERT INTO messages (event_id, state, robot, wall, t_detect, body, published_at, acked_at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (event_id, state) DO UPDATE SET "
            "body = excluded.body, wall = excluded.wall, t_detect = excluded.t_detect",
            (e.id, e.state, e.robot, item.wall, e.t_detect, json.dumps(e.to_json()), item.published_at,
             item.acked_at),
        )

    def _mark(self, event_id: str, state: str | None, column: str, when: float) -> None:
        assert self._db is not None and column in ("published_at", "acked_at")
        if state is None:
            self._db.execute(f"UPDATE messages SET {column} = ? WHERE event_id = ? AND {column} IS NULL",
                             (when, event_id))
        else:
            self._db.execute(f"UPDATE messages SET {column} = ? WHERE event_id = ? AND state = ? "
                             f"AND {column} IS NULL", (when, event_id, state))

    # ---------------------------------------------------------------- the API

    def append(self, event: FallEvent) -> FallEvent:
        """Store one message durably (fsync'd) and return it with ``wall_time`` filled in.

        Never raises on storage trouble: the message is then kept in memory, logged, and written later.
        """
        self._check_writable()
        with self._lock:
            now = self._clock()
            if not event.wall_time:
                event = replace(event, wall_time=iso(now))
            item = StoredEvent(event, now, None, None)
            self._pending[(event.id, event.state)] = item
            if self._db is None:
                self._open()
            self._flush()
            return event

    def mark_published(self, event_id: str, state: str | None = None) -> None:
        """Record that the message(s) of ``event_id`` (all states so far, or one) went out."""
        self._record(event_id, state, "published_at")

    def acknowledge(self, event_id: str, state: str | None = None) -> int:
        """A receiver confirmed the event: its messages so far (or one state) are no longer republished.

        Returns how many messages were acknowledged (0 for an unknown id).
        """
        self._check_writable()
        with self._lock:
            known = sum(1 for k, v in self._pending.items() if k[0] == event_id and v.acked_at is None
                        and (state is None or k[1] == state))
            if self._db is not None:
                try:
                    sql = "SELECT count(*) FROM messages WHERE event_id = ? AND acked_at IS NULL"
                    args: tuple = (event_id,)
                    if state is not None:
                        sql += " AND state = ?"
                        args += (state,)
                    known += self._db.execute(sql, args).fetchone()[0]
                except sqlite3.DatabaseError as exc:
                    self._fail("cannot read the event journal", exc)
            self._record(event_id, state, "acked_at")
            return known

    def _record(self, event_id: str, state: str | None, column: str) -> None:
        self._check_writable()
        with self._lock:
            now = self._clock()
            for key, item in list(self._pending.items()):
                if key[0] == event_id and (state is None or key[1] == state) and getattr(item, column) is None:
                    self._pending[key] = replace(item, **{column: now})
            if self._db is None:
                self._open()
            if self._db is None:
                self._pending_marks.append((event_id, state, column, now))
                return
            try:
                with _transaction(self._db):
                    self._mark(event_id, state, column, now)
            except (sqlite3.DatabaseError, OSError) as exc:
                self._pending_marks.append((event_id, state, column, now))
                self._fail("cannot write to the event journal", exc)

    def unacknowledged(self) -> list[FallEvent]:
        """Messages not yet acknowledged, oldest first (on disk and waiting in memory)."""
        return [s.event for s in self._select("acked_at IS NULL", (), None)]

    def unpublished(self) -> list[FallEvent]:
        """Messages never published, oldest first."""
        return [s.event for s in self._select("published_at IS NULL", (), None)]

    def query(self, since: float | None = None, until: float | None = None,
              limit: int | None = None, unacked: bool = False) -> list[StoredEvent]:
        """Messages journalled between two unix times (inclusive), only the unacknowledged ones when
        ``unacked``, oldest first, at most ``limit`` (the newest ``limit`` when more match)."""
        where, args = [], []
        if since is not None:
            where.append("wall >= ?")
            args.append(since)
        if until is not None:
            where.append("wall <= ?")
            args.append(until)
        if unacked:
            where.append("acked_at IS NULL")
        return self._select(" AND ".join(where) or "1", tuple(args), limit)

    def get(self, event_id: str) -> list[StoredEvent]:
        """All messages of one event, oldest first."""
        return self._select("event_id = ?", (event_id,), None)

    def _select(self, where: str, args: tuple, limit: int | None) -> list[StoredEvent]:
        with self._lock:
            rows: dict[tuple[str, str], StoredEvent] = {}
            if self._db is None:
                if self._readonly:
                    raise JournalError(f"the event journal {self.path} is closed")
                self._open()
                self._flush()
            if self._db is not None:
                try:
                    for body, wall, pub, ack in self._db.execute(
                        f"SELECT body, wall, published_at, acked_at FROM messages WHERE {where} "
                        "ORDER BY wall, t_detect", args
                    ):
                        event = FallEvent.from_json(json.loads(body))
                        rows[(event.id, event.state)] = StoredEvent(event, wall, pub, ack)
                except sqlite3.DatabaseError as exc:
                    if self._readonly:
                        raise JournalError(_read_error(self.path, exc)) from exc
                    self._fail("cannot read the event journal", exc)
            for key, item in self._pending.items():
                if _matches(item, where, args):
                    rows[key] = item
        out = sorted(rows.values(), key=lambda s: (s.wall, s.event.t_detect))
        if limit is not None and limit >= 0:
            out = out[-limit:] if limit else []
        return out

    def close(self) -> None:
        with self._lock:
            if not self._readonly:
                self._flush()
            self._close_db()

    def __enter__(self) -> EventJournal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _default_connect(path: Path) -> sqlite3.Connection:
    return sqlite3.connect(path, timeout=5.0, isolation_level=None, check_same_thread=False)


def _prepare(db: sqlite3.Connection) -> None:
    """The daemon's settings (WAL, fsync on every commit) and the tables, on a freshly opened file."""
    db.execute("PRAGMA journal_mode=WAL")
    db.execute("PRAGMA synchronous=FULL")
    db.executescript(_SCHEMA)


def _readonly_uri(path: Path) -> str:
    return path.absolute().as_uri() + "?mode=ro"


def _open_readonly(path: Path) -> sqlite3.Connection:
    """Open an existing journal for reading only: nothing is created, nothing is moved aside."""
    if not path.is_file():
        raise FileNotFoundError(f"no event journal at {path}: the daemon creates it with its first fall event; "
                                "check pipeline.state_dir")
    try:
        db = sqlite3.connect(_readonly_uri(path), uri=True, timeout=5.0, isolation_level=None,
                             check_same_thread=False)
    except sqlite3.Error as exc:
        raise JournalError(_read_error(path, exc)) from exc
    try:
        db.execute("SELECT count(*) FROM messages").fetchone()
    except sqlite3.Error as exc:
        db.close()
        raise JournalError(_read_error(path, exc)) from exc
    return db


def _read_error(path: Path, exc: sqlite3.Error) -> str:
    """What went wrong reading ``path`` read-only, and what to do about it."""
    text = str(exc).lower()
    if isinstance(exc, sqlite3.DatabaseError) and _is_corrupt(exc):
        fix = (f"the file is damaged; the daemon moves it aside and starts a new journal the next time it opens "
               f"it; to look at what is left: sqlite3 {path} .recover")
    elif "no such table" in text:
        fix = "this is not an event journal (no messages table); check --journal or pipeline.state_dir"
    elif "unable to open" in text or "readonly" in text or "permission" in text:
        fix = f"make {path} and its folder readable by this user (pipeline.state_dir)"
    else:
        fix = "check the file and pipeline.state_dir"
    return f"cannot read the event journal {path}: {exc}; {fix}"


class _transaction:
    def __init__(self, db: sqlite3.Connection) -> None:
        self.db = db

    def __enter__(self) -> None:
        self.db.execute("BEGIN IMMEDIATE")

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.db.execute("COMMIT")
        else:
            try:
                self.db.execute("ROLLBACK")
            except sqlite3.Error:
                pass


def _matches(item: StoredEvent, where: str, args: tuple) -> bool:
    """Evaluate the few WHERE clauses used above against an in-memory message."""
    if where == "acked_at IS NULL":
        return item.acked_at is None
    if where == "published_at IS NULL":
        return item.published_at is None
    if where == "event_id = ?":
        return item.event.id == args[0]
    ok, i = True, 0
    if "wall >= ?" in where:
        ok = ok and item.wall >= args[i]
        i += 1
    if "wall <= ?" in where:
        ok = ok and item.wall <= args[i]
    if "acked_at IS NULL" in where:
        ok = ok and item.acked_at is None
    return ok


def _is_corrupt(exc: sqlite3.DatabaseError) -> bool:
    text = str(exc).lower()
    return "not a database" in text or "malformed" in text or "corrupt" in text


def _hint(exc: BaseException) -> str:
    text = str(exc).lower()
    if "full" in text or getattr(exc, "errno", None) == 28:
        return "free disk space on the state dir's filesystem; events are kept in memory and written when it works"
    if "readonly" in text or "permission" in text or isinstance(exc, PermissionError):
        return "make the state dir writable by the daemon's user (pipeline.state_dir)"
    return "check the state dir (pipeline.state_dir); events are kept in memory and written when it works"
