"""The journal's rows: one stored message (:class:`StoredEvent`), which messages a read wants
(:class:`Selection`, the same rule in SQL and in memory) and the statements on an open connection.

A row is one state of one event, primary key ``(event_id, state)``; ``wall``, ``published_at``,
``acked_at`` and ``hooks_done_at`` are unix seconds (NULL until it happens), ``t_detect`` is on the capture
clock. ``acked_by`` is who acknowledged (the ack's free-text ``by``, NULL when it said nothing);
``hooks_outcome`` says how the message's hooks finished (:data:`HOOK_OUTCOMES`). Each hook's own progress
with a message (attempts started, how it finished) is a row of ``hook_runs``, keyed by the hook's key
(:func:`daemon.outbox.hooks.hook_key`, from its argv).

A journal written before these columns gets them when the daemon opens it (:func:`migrate`); a reader that
opens an old file read-only sees them as NULL (:func:`select_list`).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

from posed.falls.event import FallEvent

MESSAGES = """
CREATE TABLE IF NOT EXISTS messages (
    event_id      TEXT NOT NULL,
    state         TEXT NOT NULL,
    robot         TEXT NOT NULL,
    wall          REAL NOT NULL,     -- unix seconds when the detector's message was journalled
    t_detect      REAL NOT NULL,     -- capture clock (seconds)
    body          TEXT NOT NULL,     -- FallEvent.to_json()
    published_at  REAL,              -- unix seconds of the first publication, NULL = never published
    acked_at      REAL,              -- unix seconds of the acknowledgement, NULL = not acknowledged
    acked_by      TEXT,              -- who acknowledged (the ack's "by"), NULL = not said
    hooks_done_at REAL,              -- unix seconds when its hooks were done with it, NULL = not yet
    hooks_outcome TEXT,              -- HOOK_OUTCOMES, NULL while not done
    PRIMARY KEY (event_id, state)
);
"""
# after the migration (an old file has no hooks_done_at until then)
INDEXES_AND_HOOK_RUNS = """
CREATE INDEX IF NOT EXISTS messages_wall ON messages (wall);
CREATE INDEX IF NOT EXISTS messages_unacked ON messages (acked_at) WHERE acked_at IS NULL;
CREATE INDEX IF NOT EXISTS messages_hooks_pending ON messages (wall) WHERE hooks_done_at IS NULL;
CREATE TABLE IF NOT EXISTS hook_runs (
    event_id TEXT NOT NULL,
    state    TEXT NOT NULL,
    hook     TEXT NOT NULL,              -- the hook's key (hooks.hook_key: a hash of its argv)
    attempts INTEGER NOT NULL DEFAULT 0, -- runs started, across restarts (the last POSED_HOOK_ATTEMPT)
    outcome  TEXT,                       -- ok, gave_up; NULL = not finished (pending, running or cut off)
    done_at  REAL,                       -- unix seconds when it finished
    PRIMARY KEY (event_id, state, hook)
);
"""
ADDED_COLUMNS = (("acked_by", "TEXT"), ("hooks_done_at", "REAL"), ("hooks_outcome", "TEXT"))
COLUMN_NAMES = ("body", "wall", "published_at", "acked_at", "acked_by", "hooks_done_at", "hooks_outcome")
COLUMNS = ", ".join(COLUMN_NAMES)                     # what from_row reads
# a mark sets its column (a time) and these companions, once, on the messages that do not have it yet
MARKS = {"published_at": (), "acked_at": ("acked_by",), "hooks_done_at": ("hooks_outcome",)}

# how a message's hooks were done with it (hooks_outcome)
HOOK_OUTCOMES = {
    "ok": "every hook succeeded",
    "gave_up": "a hook still failed after its retries (the others succeeded or gave up too)",
    "stale": "not handed to the hooks again at a start: older than the redelivery bound",
    "no_hooks": "no hook was configured",
    "untracked": "journalled by a posed that did not record hook delivery, more than an hour before the "
                 "journal got these columns",
}
# Messages whose hooks were cut off are handed to them again at the next start when journalled less than this
# long before it; an alarm whatever its age (daemon.outbox.delivery). A journal written before hook delivery
# was recorded leaves the rows of this last stretch pending (the restart that upgraded may have cut their hooks
# off) and marks older ones "untracked".
REDELIVER_MAX_AGE_S = 3600.0


@dataclass(frozen=True)
class StoredEvent:
    """One journalled message and its delivery state (times are unix seconds)."""

    event: FallEvent
    wall: float
    published_at: float | None
    acked_at: float | None
    acked_by: str | None = None
    hooks_done_at: float | None = None
    hooks_outcome: str | None = None

    @property
    def key(self) -> tuple[str, str]:
        return self.event.id, self.event.state

    def to_json(self) -> dict:
        out = self.event.to_json()
        out["published_at"] = self.published_at
        out["acked_at"] = self.acked_at
        out["acked_by"] = self.acked_by
        out["hooks_done_at"] = self.hooks_done_at
        out["hooks_outcome"] = self.hooks_outcome
        return out


@dataclass(frozen=True)
class HookRun:
    """One hook's progress with one message: runs started so far (across restarts) and how it finished
    (``ok``, ``gave_up``; None: not finished)."""

    attempts: int = 0
    outcome: str | None = None


UNREADABLE = (ValueError, KeyError, TypeError, AttributeError)   # what from_row raises on a damaged row


def from_row(row: tuple) -> StoredEvent:
    """A ``SELECT {COLUMNS}`` row; raises one of :data:`UNREADABLE` on a row that is not a message (a body that
    is not an event, a time that is not a number)."""
    body, wall, published_at, acked_at, acked_by, hooks_done_at, hooks_outcome = row
    obj = json.loads(body)
    if not isinstance(obj, dict):
        raise ValueError(f"the body is a JSON {type(obj).__name__}, not an event object")
    for name, value in (("wall", wall), ("published_at", published_at), ("acked_at", acked_at),
                        ("hooks_done_at", hooks_done_at)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise ValueError(f"{name} is {value!r}, not unix seconds")
    return StoredEvent(FallEvent.from_json(obj), float(wall), published_at, acked_at, acked_by,
                       hooks_done_at, hooks_outcome)


def table_columns(db: sqlite3.Connection, table: str) -> set[str]:
    """The column names ``table`` has in this file (a file of an older posed may lack some)."""
    return {r[1] for r in db.execute(f"PRAGMA table_info({table})")}


def select_list(db: sqlite3.Connection) -> str:
    """:data:`COLUMNS` as this file has them: a column an old journal lacks (read-only readers do not migrate
    it) reads as NULL."""
    have = table_columns(db, "messages")
    return ", ".join(c if c in have else f"NULL AS {c}" for c in COLUMN_NAMES)


def migrate(db: sqlite3.Connection, clock: Callable[[], float]) -> dict | None:
    """Add the columns a journal written by an older posed lacks (in one transaction). Its rows' hooks are
    marked done (``untracked``) when journalled more than :data:`REDELIVER_MAX_AGE_S` before now (``clock``:
    unix seconds); the newer ones stay pending. Returns what was done (None: nothing to do)."""
    have = table_columns(db, "messages")
    if all(c in have for c, _ in ADDED_COLUMNS):
        return None
    db.execute("BEGIN IMMEDIATE")
    try:
        have = table_columns(db, "messages")    # another process may have done it
        added = [c for c, _ in ADDED_COLUMNS if c not in have]
        for column, kind in ADDED_COLUMNS:
            if column in added:
                db.execute(f"ALTER TABLE messages ADD COLUMN {column} {kind}")
        untracked = pending = 0
        if "hooks_done_at" in added:
            now = clock()
            untracked = db.execute("UPDATE messages SET hooks_done_at = ?, hooks_outcome = 'untracked' "
                                   "WHERE wall < ?", (now, now - REDELIVER_MAX_AGE_S)).rowcount
            pending = db.execute("SELECT count(*) FROM messages WHERE hooks_done_at IS NULL").fetchone()[0]
        db.execute("COMMIT")
    except BaseException:
        try:
            db.execute("ROLLBACK")
        except sqlite3.Error:
            pass
        raise
    return {"added": added, "untracked": untracked, "pending": pending} if added else None


@dataclass(frozen=True)
class Selection:
    """Which messages a read wants: all conditions must hold (unix seconds, inclusive bounds)."""

    since: float | None = None
    until: float | None = None
    event_id: str | None = None
    unacked: bool = False
    unpublished: bool = False
    hooks_pending: bool = False

    def where(self) -> tuple[str, tuple]:
        """The SQL condition and its arguments."""
        clauses, args = [], []
        for clause, value in (("wall >= ?", self.since), ("wall <= ?", self.until),
                              ("event_id = ?", self.event_id)):
            if value is not None:
                clauses.append(clause)
                args.append(value)
        if self.unacked:
            clauses.append("acked_at IS NULL")
        if self.unpublished:
            clauses.append("published_at IS NULL")
        if self.hooks_pending:
            clauses.append("hooks_done_at IS NULL")
        return " AND ".join(clauses) or "1", tuple(args)

    def matches(self, item: StoredEvent) -> bool:
        """The same condition on a message waiting in memory."""
        return ((self.since is None or item.wall >= self.since)
                and (self.until is None or item.wall <= self.until)
                and (self.event_id is None or item.event.id == self.event_id)
                and (not self.unacked or item.acked_at is None)
                and (not self.unpublished or item.published_at is None)
                and (not self.hooks_pending or item.hooks_done_at is None))


def select(db: sqlite3.Connection, selection: Selection,
           unreadable: Callable[[int, Exception], None] | None = None) -> Iterator[StoredEvent]:
    """The stored messages ``selection`` wants, oldest first, as SQLite reads them. A row that is not a message
    (damaged by hand, by a disk, by a bug) is skipped and handed to ``unreadable`` (its rowid, the error), so one
    bad row never hides the others (nor stops the publisher at its start)."""
    where, args = selection.where()
    yield from readable(db.execute(f"SELECT rowid, {select_list(db)} FROM messages WHERE {where} "
                                   "ORDER BY wall, t_detect", args), unreadable)


def readable(found: Iterable[tuple], unreadable: Callable[[int, Exception], None] | None = None
             ) -> Iterator[StoredEvent]:
    """The messages of ``SELECT rowid, {COLUMNS}`` rows; the rows that are not messages go to ``unreadable``."""
    for rowid, *row in found:
        try:
            item = from_row(tuple(row))
        except UNREADABLE as exc:
            if unreadable is not None:
                unreadable(rowid, exc)
            continue
        yield item


def count_unacked(db: sqlite3.Connection, event_id: str, state: str | None) -> int:
    """How many stored messages of ``event_id`` (all states, or one) are not acknowledged."""
    sql = "SELECT count(*) FROM messages WHERE event_id = ? AND acked_at IS NULL"
    args: tuple = (event_id,)
    if state is not None:
        sql += " AND state = ?"
        args += (state,)
    return db.execute(sql, args).fetchone()[0]


def insert(db: sqlite3.Connection, item: StoredEvent) -> None:
    """Store a message; a message already there (same id and state) gets the new body and times, and the
    delivery marks it lacks (a hooks mark only with its outcome)."""
    e = item.event
    db.execute(
        "INSERT INTO messages (event_id, state, robot, wall, t_detect, body, published_at, acked_at, acked_by, "
        "hooks_done_at, hooks_outcome) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
        "ON CONFLICT (event_id, state) DO UPDATE SET "
        "body = excluded.body, wall = excluded.wall, t_detect = excluded.t_detect, "
        "published_at = coalesce(published_at, excluded.published_at), "
        "acked_by = CASE WHEN acked_at IS NULL THEN excluded.acked_by ELSE acked_by END, "
        "acked_at = coalesce(acked_at, excluded.acked_at), "
        "hooks_outcome = CASE WHEN hooks_done_at IS NULL THEN excluded.hooks_outcome ELSE hooks_outcome END, "
        "hooks_done_at = coalesce(hooks_done_at, excluded.hooks_done_at)",
        (e.id, e.state, e.robot, item.wall, e.t_detect, json.dumps(e.to_json()), item.published_at,
         item.acked_at, item.acked_by, item.hooks_done_at, item.hooks_outcome),
    )


def mark(db: sqlite3.Connection, event_id: str, state: str | None, column: str, when: float,
         extra: dict | None = None) -> None:
    """Set ``column`` (published_at, acked_at or hooks_done_at) to ``when``, and its companions (:data:`MARKS`)
    to ``extra``, on the messages of ``event_id`` (all states, or one) that do not have it yet."""
    extra = extra or {}
    assert column in MARKS and set(extra) <= set(MARKS[column])
    sets = ", ".join([f"{column} = ?", *(f"{k} = ?" for k in extra)])
    args: tuple = (when, *extra.values(), event_id)
    where = f"event_id = ? AND {column} IS NULL"
    if state is not None:
        where += " AND state = ?"
        args += (state,)
    db.execute(f"UPDATE messages SET {sets} WHERE {where}", args)


def hook_started(db: sqlite3.Connection, event_id: str, state: str, hook: str, attempt: int) -> None:
    """Record that run ``attempt`` of ``hook`` for the message is starting (before it starts)."""
    db.execute("INSERT INTO hook_runs (event_id, state, hook, attempts) VALUES (?, ?, ?, ?) "
               "ON CONFLICT (event_id, state, hook) DO UPDATE SET attempts = max(attempts, excluded.attempts)",
               (event_id, state, hook, attempt))


def hook_finished(db: sqlite3.Connection, event_id: str, state: str, hook: str, outcome: str, when: float) -> None:
    """Record that ``hook`` is done with the message (``ok`` or ``gave_up``)."""
    db.execute("INSERT INTO hook_runs (event_id, state, hook, outcome, done_at) VALUES (?, ?, ?, ?, ?) "
               "ON CONFLICT (event_id, state, hook) DO UPDATE SET outcome = excluded.outcome, "
               "done_at = excluded.done_at", (event_id, state, hook, outcome, when))


def hook_runs(db: sqlite3.Connection, keys: set[tuple[str, str]]) -> dict[tuple[str, str], dict[str, HookRun]]:
    """The hooks' progress with the messages ``keys`` ((event id, state) pairs): message -> hook key -> run."""
    out: dict[tuple[str, str], dict[str, HookRun]] = {}
    ids = sorted({k[0] for k in keys})
    for i in range(0, len(ids), 500):                    # SQLite's limit on the number of parameters
        chunk = ids[i:i + 500]
        for event_id, state, hook, attempts, outcome in db.execute(
                f"SELECT event_id, state, hook, attempts, outcome FROM hook_runs WHERE event_id IN "
                f"({', '.join('?' * len(chunk))})", chunk):
            if (event_id, state) in keys:
                out.setdefault((event_id, state), {})[hook] = HookRun(attempts, outcome)
    return out
