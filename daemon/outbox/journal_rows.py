"""The journal's rows: one stored message (:class:`StoredEvent`), which messages a read wants
(:class:`Selection`, the same rule in SQL and in memory) and the statements on an open connection.

A row is one state of one event, primary key ``(event_id, state)``; ``wall``, ``published_at`` and
``acked_at`` are unix seconds (NULL until it happens), ``t_detect`` is on the capture clock.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass

from posed.falls.event import FallEvent

SCHEMA = """
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
COLUMNS = "body, wall, published_at, acked_at"       # what from_row reads
DELIVERY_COLUMNS = ("published_at", "acked_at")


@dataclass(frozen=True)
class StoredEvent:
    """One journalled message and its delivery state (times are unix seconds)."""

    event: FallEvent
    wall: float
    published_at: float | None
    acked_at: float | None

    @property
    def key(self) -> tuple[str, str]:
        return self.event.id, self.event.state

    def to_json(self) -> dict:
        out = self.event.to_json()
        out["published_at"] = self.published_at
        out["acked_at"] = self.acked_at
        return out


def from_row(row: tuple) -> StoredEvent:
    """A ``SELECT {COLUMNS}`` row; raises ValueError/KeyError/TypeError on a body that is not an event."""
    body, wall, published_at, acked_at = row
    return StoredEvent(FallEvent.from_json(json.loads(body)), wall, published_at, acked_at)


@dataclass(frozen=True)
class Selection:
    """Which messages a read wants: all conditions must hold (unix seconds, inclusive bounds)."""

    since: float | None = None
    until: float | None = None
    event_id: str | None = None
    unacked: bool = False
    unpublished: bool = False

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
        return " AND ".join(clauses) or "1", tuple(args)

    def matches(self, item: StoredEvent) -> bool:
        """The same condition on a message waiting in memory."""
        return ((self.since is None or item.wall >= self.since)
                and (self.until is None or item.wall <= self.until)
                and (self.event_id is None or item.event.id == self.event_id)
                and (not self.unacked or item.acked_at is None)
                and (not self.unpublished or item.published_at is None))


def select(db: sqlite3.Connection, selection: Selection) -> Iterator[StoredEvent]:
    """The stored messages ``selection`` wants, oldest first, as SQLite reads them."""
    where, args = selection.where()
    for row in db.execute(f"SELECT {COLUMNS} FROM messages WHERE {where} ORDER BY wall, t_detect", args):
        yield from_row(row)


def count_unacked(db: sqlite3.Connection, event_id: str, state: str | None) -> int:
    """How many stored messages of ``event_id`` (all states, or one) are not acknowledged."""
    sql = "SELECT count(*) FROM messages WHERE event_id = ? AND acked_at IS NULL"
    args: tuple = (event_id,)
    if state is not None:
        sql += " AND state = ?"
        args += (state,)
    return db.execute(sql, args).fetchone()[0]


def insert(db: sqlite3.Connection, item: StoredEvent) -> None:
    """Store a message; a message already there (same id and state) gets the new body and times."""
    e = item.event
    db.execute(
        "INSERT INTO messages (event_id, state, robot, wall, t_detect, body, published_at, acked_at) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (event_id, state) DO UPDATE SET "
        "body = excluded.body, wall = excluded.wall, t_detect = excluded.t_detect",
        (e.id, e.state, e.robot, item.wall, e.t_detect, json.dumps(e.to_json()), item.published_at,
         item.acked_at),
    )


def mark(db: sqlite3.Connection, event_id: str, state: str | None, column: str, when: float) -> None:
    """Set ``column`` (published_at or acked_at) to ``when`` on the messages of ``event_id`` (all states, or
    one) that do not have it yet."""
    assert column in DELIVERY_COLUMNS
    if state is None:
        db.execute(f"UPDATE messages SET {column} = ? WHERE event_id = ? AND {column} IS NULL",
                   (when, event_id))
    else:
        db.execute(f"UPDATE messages SET {column} = ? WHERE event_id = ? AND state = ? "
                   f"AND {column} IS NULL", (when, event_id, state))
