"""The journal's SQLite file: opening it for the daemon (WAL, ``synchronous=FULL``) or read-only, committing,
recognising a corrupt file and setting it aside, and saying what went wrong and how to fix it."""

from __future__ import annotations

import sqlite3
import time
from collections.abc import Callable
from pathlib import Path

from posed.daemon.outbox import journal_rows as rows


class JournalError(RuntimeError):
    """The journal cannot be used at all (raised by ``EventJournal(path, strict=True)`` and by a read-only
    journal that cannot read its file)."""


BUSY_TIMEOUT_S = 0.5
# How long the daemon's journal waits for a lock another process holds (an sqlite3 shell with a transaction open,
# a backup tool). The publisher's threads share one connection (no wait among them), and readers (posed events)
# never block a WAL writer, so a lock is someone else's; waiting 5 s on each write (as before) stopped the
# publisher's heartbeat for the watchdog's 5 s: it was killed as stuck, again and again, and the daemon escalated.
# Past this the message waits in memory and the fallback file, as on a full disk.


def default_connect(path: Path) -> sqlite3.Connection:
    """The daemon's connection: autocommit (transactions are explicit), :data:`BUSY_TIMEOUT_S` busy timeout,
    any thread; the file is created (or kept) private, mode 0600 (:mod:`daemon.outbox.private`)."""
    from posed.daemon.outbox.private import private_file

    private_file(path)
    return sqlite3.connect(path, timeout=BUSY_TIMEOUT_S, isolation_level=None, check_same_thread=False)


def prepare(db: sqlite3.Connection, clock: Callable[[], float] = time.time) -> dict | None:
    """The daemon's settings (WAL, fsync on every commit) and the tables, on a freshly opened file; a journal
    written by an older posed gets the columns it lacks (:func:`journal_rows.migrate`, ``clock``: unix seconds).
    Returns what the migration did (None: nothing)."""
    db.execute("PRAGMA journal_mode=WAL")
    db.execute("PRAGMA synchronous=FULL")
    db.executescript(rows.MESSAGES)
    migrated = rows.migrate(db, clock)
    db.executescript(rows.INDEXES_AND_HOOK_RUNS)
    return migrated


def readonly_uri(path: Path) -> str:
    return path.absolute().as_uri() + "?mode=ro"


def open_readonly(path: Path) -> sqlite3.Connection:
    """Open an existing journal for reading only: nothing is created, nothing is moved aside."""
    if not path.is_file():
        raise FileNotFoundError(f"no event journal at {path}: the daemon creates it with its first fall event; "
                                "check pipeline.state_dir")
    try:
        db = sqlite3.connect(readonly_uri(path), uri=True, timeout=5.0, isolation_level=None,
                             check_same_thread=False)
    except sqlite3.Error as exc:
        raise JournalError(read_error(path, exc)) from exc
    try:
        db.execute("SELECT count(*) FROM messages").fetchone()
    except sqlite3.Error as exc:
        being_created = _no_tables(db)
        db.close()
        if being_created:   # the daemon made the file and has not written its table yet: no event so far
            raise FileNotFoundError(f"no event journal at {path} yet: the daemon is creating it (with its first "
                                    "fall event); ask again in a moment") from exc
        raise JournalError(read_error(path, exc)) from exc
    return db


def _no_tables(db: sqlite3.Connection) -> bool:
    """Whether the file holds no table at all (created a moment ago, its schema not yet committed)."""
    try:
        return db.execute("SELECT count(*) FROM sqlite_master").fetchone()[0] == 0
    except sqlite3.Error:
        return False


class Transaction:
    """``with Transaction(db):`` — BEGIN IMMEDIATE, then COMMIT (fsync'd), or ROLLBACK on an exception."""

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


# ------------------------------------------------------------------------------------------ a corrupt file

def is_corrupt(exc: sqlite3.DatabaseError) -> bool:
    text = str(exc).lower()
    return "not a database" in text or "malformed" in text or "corrupt" in text


def salvage(path: Path) -> list[rows.StoredEvent]:
    """The unacknowledged messages that can still be read from a damaged file (the others are skipped)."""
    out: list[rows.StoredEvent] = []
    try:
        db = sqlite3.connect(readonly_uri(path), uri=True, timeout=1.0)
        try:
            found = db.execute(f"SELECT {rows.select_list(db)} FROM messages WHERE acked_at IS NULL").fetchall()
        finally:
            db.close()
    except sqlite3.DatabaseError:
        return out
    for row in found:
        try:
            out.append(rows.from_row(row))
        except rows.UNREADABLE:
            continue
    return out


def snapshot_rows(path: Path, where: str, args: tuple) -> list[tuple]:
    """The rows ``where`` selects (``rowid`` first, then :data:`journal_rows.COLUMNS`) from a journal the daemon
    cannot open (a read-only or full state directory): read from a copy of the file and its write-ahead log in a
    temporary folder, since SQLite cannot open a WAL journal where it cannot create its ``-shm`` file, and the
    messages a kill -9 left in the ``-wal`` (the fall just before it) are only there. Raises OSError or
    sqlite3.Error when even that fails."""
    import shutil
    import tempfile

    with tempfile.TemporaryDirectory(prefix="posed-journal-") as folder:
        copy = Path(folder) / path.name
        shutil.copyfile(path, copy)
        wal = Path(f"{path}-wal")
        if wal.exists():
            shutil.copyfile(wal, Path(f"{copy}-wal"))
        db = sqlite3.connect(copy, timeout=1.0)
        try:
            return db.execute(f"SELECT rowid, {rows.select_list(db)} FROM messages WHERE {where} "
                              "ORDER BY wall, t_detect", args).fetchall()
        finally:
            db.close()


def set_aside(path: Path, unix_time: float) -> Path:
    """Rename the file and its WAL and shared-memory files to ``<name>.corrupt-<unix time>``; returns the
    new name of the main file (a rename that fails is skipped)."""
    aside = path.with_name(f"{path.name}.corrupt-{int(unix_time)}")
    for suffix in ("", "-wal", "-shm"):
        src = Path(str(path) + suffix)
        if src.exists():
            try:
                src.rename(Path(str(aside) + suffix))
            except OSError:
                pass
    return aside


# ------------------------------------------------------------------------------------------ what to do

def read_error(path: Path, exc: sqlite3.Error) -> str:
    """What went wrong reading ``path`` read-only, and what to do about it."""
    text = str(exc).lower()
    if isinstance(exc, sqlite3.DatabaseError) and is_corrupt(exc):
        fix = (f"the file is damaged; the daemon moves it aside and starts a new journal the next time it opens "
               f"it; to look at what is left: sqlite3 {path} .recover")
    elif "no such table" in text:
        fix = "this is not an event journal (no messages table); check --journal or pipeline.state_dir"
    elif "unable to open" in text or "readonly" in text or "permission" in text:
        fix = f"make {path} and its folder readable by this user (pipeline.state_dir)"
    else:
        fix = "check the file and pipeline.state_dir"
    return f"cannot read the event journal {path}: {exc}; {fix}"


def write_hint(exc: BaseException) -> str:
    """The fix for a failure to open or write the daemon's journal."""
    text = str(exc).lower()
    if "full" in text or getattr(exc, "errno", None) == 28:
        return "free disk space on the state dir's filesystem; events are kept in memory and written when it works"
    if "readonly" in text or "permission" in text or isinstance(exc, PermissionError):
        return "make the state dir writable by the daemon's user (pipeline.state_dir)"
    if "locked" in text or "busy" in text:
        return ("another process holds the journal locked (an sqlite3 shell with a transaction open, a backup "
                "tool: fuser -v the file); end it; events are kept in memory and written when it is released")
    return "check the state dir (pipeline.state_dir); events are kept in memory and written when it works"
