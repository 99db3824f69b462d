"""The fall-event journal: every event message is on disk before it is published, and kept until acknowledged.

One SQLite file (``events.sqlite3`` in the state dir), WAL mode, ``synchronous=FULL``: each commit fsyncs the
write-ahead log, so a message whose ``append`` returned survives a kill -9 or a power loss. A message is one
state of one event (``falling``, ``on_floor``, ``alarm``, ``recovered``); updates keep the event's ``id``.

Life of a message: ``append`` (stored, unpublished) -> ``mark_published`` -> ``acknowledge`` (a receiver
confirmed it, and said who: ``acked_by``). ``unacknowledged()`` is what the publisher republishes after a restart
or a reconnect. Apart from that, its hooks: ``hook_started`` before each run of each hook (how many runs each
hook started, across restarts), ``hook_finished`` when a hook succeeded or gave up, ``mark_hooks_done`` when
every hook is done with it; ``hooks_pending()`` is what the publisher hands to the hooks again at its start
(:mod:`daemon.outbox.delivery`).

When the disk is full, the file is not writable or the database is corrupt, the journal says so in one clear
log line (then at most one a minute while it lasts), keeps the messages in memory (they are still returned by
``unacknowledged`` and ``query``) and in the fallback file (:mod:`daemon.outbox.fallback`, a tmpfs that
survives a restart of the daemon; taken back at the next start) and writes them on the next call, or on
``retry()``. A corrupt file is moved aside (``*.corrupt-<unix time>``)
after salvaging the unacknowledged rows that can still be read, and a fresh journal is started.

``EventJournal(path, readonly=True)`` is for readers other than the daemon (``posed events``, ``posed plot``):
it opens the file read-only, creates nothing, never moves a file aside and never logs; a file it cannot read
raises ``JournalError`` naming the file and the fix.

This module holds the journal's logic (what waits in memory, failures, the API); the rows, the selections and
the SQL statements are in :mod:`daemon.outbox.journal_rows`, opening and diagnosing the file in
:mod:`daemon.outbox.journal_file`.
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from posed.daemon import logs
from posed.daemon.clock import iso
from posed.daemon.outbox import journal_file as jfile
from posed.daemon.outbox import journal_rows as rows
from posed.daemon.outbox.fallback import FallbackStore
from posed.daemon.outbox.journal_file import JournalError
from posed.daemon.outbox.journal_rows import Selection, StoredEvent
from posed.falls.event import FallEvent

__all__ = ["EventJournal", "JournalError", "StoredEvent"]


class EventJournal:
    """SQLite journal of fall-event messages; thread-safe (the publisher and Zenoh callbacks share it)."""

    LOG_EVERY_S = 60.0          # while the same trouble lasts, one log line a minute

    def __init__(self, path: str | os.PathLike, strict: bool = False, clock=time.time,
                 connect: Callable[[Path], sqlite3.Connection] | None = None, readonly: bool = False,
                 fallback: FallbackStore | None = None) -> None:
        """``connect`` opens the file (default: ``sqlite3.connect`` with a 5 s busy timeout); tests pass one
        that limits the file's size to meet a real SQLITE_FULL. ``clock``: unix seconds.

        ``readonly``: only read an existing journal (raises FileNotFoundError when there is none, JournalError
        when it cannot be read); the writing methods then raise JournalError.

        ``fallback``: where messages that cannot be stored wait across a restart; what it holds is taken back
        first (``restored``).
        """
        self.path = Path(path)
        self._readonly = readonly
        self._clock = clock
        self._connect = connect or jfile.default_connect
        self._lock = threading.RLock()
        self._db: sqlite3.Connection | None = None
        # (event_id, state) -> StoredEvent not yet on disk, plus delivery updates not yet on disk
        self._pending: dict[tuple[str, str], StoredEvent] = {}
        self._pending_marks: list[tuple[str, str | None, str, float, dict]] = []
        # hook_runs writes not yet on disk: (journal_rows function, its arguments after the connection); only in
        # memory (a lost one costs at most a hook run again at the next start)
        self._pending_hook_rows: list[tuple[Callable, tuple]] = []
        self.last_error: str = ""
        self._log = logs.get("journal", path=str(self.path))
        self._fallback = None if readonly else fallback
        self._fallback_saved: tuple | None = None
        self._next_log = 0.0
        self.suppressed_logs = 0
        self.restored = 0
        self.unreadable_rows: dict[int, str] = {}    # rowid -> what is wrong with it (said once per row)
        self._snapshot_of: tuple | None = None        # (file stamps, messages) read from a copy (_snapshot)
        if readonly:
            self._db = jfile.open_readonly(self.path)
            return
        with self._lock:
            if self._fallback is not None:
                for item in self._fallback.load():
                    if item.key not in self._pending:
                        self._pending[item.key] = item
                        self.restored += 1
                if self.restored:
                    self._log.warning("journal_restored_unstored", restored=self.restored,
                                      fallback=str(self._fallback.path),
                                      note="fall-event messages the last run could not store; written to the "
                                           "journal now if it can take them, and republished until acknowledged")
            self._open()
            if self._db is not None and self._pending:
                self._flush()
            self._sync_fallback()
        if strict and self._db is None:
            raise JournalError(self.last_error)

    # ---------------------------------------------------------------- opening and failures

    def _open(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            db = self._connect(self.path)
            try:
                migrated = jfile.prepare(db, self._clock)
                db.execute("SELECT count(*) FROM messages").fetchone()
            except sqlite3.DatabaseError:
                db.close()
                raise
        except sqlite3.DatabaseError as exc:
            if jfile.is_corrupt(exc):
                self._set_aside_corrupt(exc)
                return
            self._fail("cannot open the event journal", exc)
            return
        except OSError as exc:
            self._fail("cannot create the event journal's folder", exc)
            return
        self._db = db
        if migrated:
            self._log_migrated(migrated)

    def _written(self) -> None:
        """A write went through: the trouble, if any, is over (said once). Not on opening alone: a file that
        opens but cannot be written (locked by another process) would be 'recovered' and 'unavailable' again
        at every call, two log lines a second."""
        if self.last_error:
            self._log.info("journal_recovered", previous_error=self.last_error)
            self.last_error = ""

    def _log_migrated(self, migrated: dict) -> None:
        self._log.info("journal_migrated", added_columns=migrated["added"], hooks_untracked=migrated["untracked"],
                       hooks_pending=migrated["pending"],
                       note=f"a journal of an older posed: messages journalled more than "
                            f"{rows.REDELIVER_MAX_AGE_S:g} s ago count as done by their hooks (untracked); the "
                            "newer ones are handed to the hooks again")

    def _set_aside_corrupt(self, exc: Exception) -> None:
        salvaged = jfile.salvage(self.path)
        aside = jfile.set_aside(self.path, self._clock())
        self._log.error("journal_corrupt", error=str(exc), moved_to=str(aside), salvaged=len(salvaged),
                        fix="the corrupt file was moved aside and a new journal started; inspect or delete "
                            f"{aside} (sqlite3 {aside} .recover)")
        for item in salvaged:
            self._pending.setdefault(item.key, item)
        self._db = None
        try:
            db = self._connect(self.path)
            jfile.prepare(db, self._clock)
            self._db = db
            self.last_error = ""
        except (sqlite3.DatabaseError, OSError) as exc2:
            self._fail("cannot create a fresh event journal after setting the corrupt one aside", exc2)
            return
        self._flush()

    def _fail(self, what: str, exc: BaseException) -> None:
        message = f"{what} {self.path}: {exc}"
        now = time.monotonic()
        if (message != self.last_error and not self.last_error) or now >= self._next_log:
            self._next_log = now + self.LOG_EVERY_S
            self._log.error("journal_unavailable", error=message, fix=jfile.write_hint(exc),
                            kept_in_memory=len(self._pending),
                            fallback=str(self._fallback.path) if self._fallback is not None else None,
                            suppressed=self.suppressed_logs)
            self.suppressed_logs = 0
        else:
            self.suppressed_logs += 1
        self.last_error = message
        self._close_db()

    def _sync_fallback(self) -> None:
        """The fallback file holds exactly the messages waiting in memory (none: no file)."""
        if self._fallback is None:
            return
        items = sorted(self._pending.values(), key=lambda s: (s.wall, s.event.t_detect))
        signature = tuple((i.key, i.published_at, i.acked_at, i.acked_by, i.hooks_done_at) for i in items)
        if signature == self._fallback_saved:
            return
        if items:
            ok = self._fallback.save(items)
            if not ok:
                self._log.error("fallback_unwritable", error=self._fallback.last_error, kept_in_memory=len(items),
                                fix="the messages are only in memory: free the state directory's disk or make "
                                    "it writable; RUNTIME_DIRECTORY or /run must be writable for the fallback")
        else:
            self._fallback.clear()
            ok = True
        self._fallback_saved = signature if ok else None

    @property
    def fallback_path(self) -> Path | None:
        return self._fallback.path if self._fallback is not None else None

    @property
    def fallback_error(self) -> str:
        return self._fallback.last_error if self._fallback is not None else ""

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
            return (self._db is not None and not self._pending and not self._pending_marks
                    and not self._pending_hook_rows)

    @property
    def pending_in_memory(self) -> int:
        with self._lock:
            return len(self._pending)

    def retry(self) -> bool:
        """Try again to open the file and write what waits in memory; True when everything is on disk."""
        self._check_writable()
        with self._lock:
            was_open = self._db is not None
            if self._db is None:
                self._open()
            if self._db is not None:
                self._flush()
            if was_open and self._db is None:     # a connection opened while the file was read-only stays so
                self._open()
                if self._db is not None:
                    self._flush()
            self._sync_fallback()
            return (self._db is not None and not self._pending and not self._pending_marks
                    and not self._pending_hook_rows)

    def _flush(self) -> None:
        if self._db is None:
            return
        try:
            with jfile.Transaction(self._db):
                for item in self._pending.values():
                    rows.insert(self._db, item)
                for event_id, state, column, when, extra in self._pending_marks:
                    rows.mark(self._db, event_id, state, column, when, extra)
                for write, args in self._pending_hook_rows:
                    write(self._db, *args)
        except (sqlite3.DatabaseError, OSError) as exc:
            self._fail("cannot write to the event journal", exc)
            return
        self._pending.clear()
        self._pending_marks.clear()
        self._pending_hook_rows.clear()
        self._written()

    # ---------------------------------------------------------------- the API

    def wall_now(self) -> float:
        """Now on the journal's clock (unix seconds): what ``wall`` and the delivery times are measured on."""
        return self._clock()

    def append(self, event: FallEvent, hooks_outcome: str | None = None) -> FallEvent:
        """Store one message durably (fsync'd) and return it with ``wall_time`` filled in. ``hooks_outcome``:
        the message is stored with its hooks already done (``no_hooks``: none is configured).

        Never raises on storage trouble: the message is then kept in memory, logged, and written later.
        """
        self._check_writable()
        with self._lock:
            now = self._clock()
            if not event.wall_time:
                event = replace(event, wall_time=iso(now))
            item = StoredEvent(event, now, None, None, None, None if hooks_outcome is None else now, hooks_outcome)
            self._pending[item.key] = item
            if self._db is None:
                self._open()
            self._flush()
            self._sync_fallback()
            return event

    def mark_published(self, event_id: str, state: str | None = None) -> None:
        """Record that the message(s) of ``event_id`` (all states so far, or one) went out."""
        self._record([(event_id, state)], "published_at")

    def acknowledge(self, event_id: str, state: str | None = None, by: str | None = None) -> int:
        """A receiver confirmed the event: its messages so far (or one state) are no longer republished.
        ``by``: who acknowledged (free text, kept as ``acked_by``; a message keeps its first acknowledgement's).

        Returns how many messages were acknowledged (0 for an unknown id).
        """
        self._check_writable()
        with self._lock:
            known = sum(1 for k, v in self._pending.items() if k[0] == event_id and v.acked_at is None
                        and (state is None or k[1] == state))
            if self._db is not None:
                try:
                    known += rows.count_unacked(self._db, event_id, state)
                except sqlite3.DatabaseError as exc:
                    self._fail("cannot read the event journal", exc)
                    known = max(known, 1)        # unreadable: record the acknowledgement for later
            else:                                # the file cannot be opened: what it holds, from a copy
                known += sum(1 for item in self._snapshot(Selection(event_id=event_id, unacked=True))
                             if item.key not in self._pending and (state is None or item.event.state == state))
            if known:                            # nothing to mark: no write (a flood of unknown ids is cheap)
                self._record([(event_id, state)], "acked_at", {"acked_by": by})
            return known

    def mark_hooks_done(self, event_id: str, state: str, outcome: str) -> None:
        """Every hook is done with the message (``outcome``: one of ``journal_rows.HOOK_OUTCOMES``): it is not
        handed to the hooks again."""
        assert outcome in rows.HOOK_OUTCOMES, outcome
        self._record([(event_id, state)], "hooks_done_at", {"hooks_outcome": outcome})

    def mark_hooks_done_many(self, messages: list[tuple[str, str]], outcome: str) -> None:
        """:meth:`mark_hooks_done` for each (event id, state) of ``messages``, in one write (one fsync)."""
        assert outcome in rows.HOOK_OUTCOMES, outcome
        if messages:
            self._record(messages, "hooks_done_at", {"hooks_outcome": outcome})

    def _record(self, messages: list[tuple[str, str | None]], column: str, extra: dict | None = None) -> None:
        """Mark ``column`` (with ``extra``) now on each (event id, state; None: every state) of ``messages``, in
        memory and in one write; kept in memory to be written later when the file cannot take it."""
        self._check_writable()
        extra = extra or {}
        exact = {(event_id, state) for event_id, state in messages if state is not None}
        every_state = {event_id for event_id, state in messages if state is None}
        with self._lock:
            now = self._clock()
            for key, item in list(self._pending.items()):
                if (key in exact or key[0] in every_state) and getattr(item, column) is None:
                    self._pending[key] = replace(item, **{column: now}, **extra)
            marks = [(event_id, state, column, now, extra) for event_id, state in messages]
            if self._db is None:
                self._open()
            if self._db is None:
                self._pending_marks.extend(marks)
                self._sync_fallback()
                return
            try:
                with jfile.Transaction(self._db):
                    for mark in marks:
                        rows.mark(self._db, *mark)
                self._written()
            except (sqlite3.DatabaseError, OSError) as exc:
                self._pending_marks.extend(marks)
                self._fail("cannot write to the event journal", exc)
            self._sync_fallback()

    def hook_started(self, event_id: str, state: str, hook: str, attempt: int) -> None:
        """Run ``attempt`` (1, 2, ... across restarts) of the hook whose key is ``hook`` is about to start."""
        self._write_hook_row(rows.hook_started, (event_id, state, hook, attempt))

    def hook_finished(self, event_id: str, state: str, hook: str, outcome: str) -> None:
        """The hook whose key is ``hook`` is done with the message: ``ok`` or ``gave_up``."""
        self._write_hook_row(rows.hook_finished, (event_id, state, hook, outcome, self._clock()))

    def _write_hook_row(self, write: Callable, args: tuple) -> None:
        self._check_writable()
        with self._lock:
            if self._db is None:
                self._open()
            if self._db is not None and not self._pending_hook_rows:
                try:
                    with jfile.Transaction(self._db):
                        write(self._db, *args)
                    self._written()
                    return
                except (sqlite3.DatabaseError, OSError) as exc:
                    self._fail("cannot write to the event journal", exc)
            self._pending_hook_rows.append((write, args))     # in order, after those already waiting
            if self._db is not None:
                self._flush()

    def hooks_pending(self) -> list[tuple[StoredEvent, dict[str, rows.HookRun]]]:
        """Messages whose hooks are not done, oldest first, each with what each hook did with it so far (hook
        key -> :class:`journal_rows.HookRun`; a hook missing there never started on it)."""
        pending = self._select(Selection(hooks_pending=True), None)
        keys = {s.key for s in pending}
        runs: dict[tuple[str, str], dict[str, rows.HookRun]] = {}
        with self._lock:
            if self._db is not None and keys:
                try:
                    runs = rows.hook_runs(self._db, keys)
                except sqlite3.DatabaseError as exc:
                    self._fail("cannot read the event journal", exc)
            for write, args in self._pending_hook_rows:           # what waits in memory, in order
                key, hook = (args[0], args[1]), args[2]
                if key not in keys:
                    continue
                run = runs.setdefault(key, {}).get(hook, rows.HookRun())
                if write is rows.hook_started:
                    run = replace(run, attempts=max(run.attempts, args[3]))
                else:
                    run = replace(run, outcome=args[3])
                runs[key][hook] = run
        return [(s, runs.get(s.key, {})) for s in pending]

    def unacknowledged(self) -> list[FallEvent]:
        """Messages not yet acknowledged, oldest first (on disk and waiting in memory)."""
        return [s.event for s in self._select(Selection(unacked=True), None)]

    def unpublished(self) -> list[FallEvent]:
        """Messages never published, oldest first."""
        return [s.event for s in self._select(Selection(unpublished=True), None)]

    def query(self, since: float | None = None, until: float | None = None,
              limit: int | None = None, unacked: bool = False, event_id: str | None = None) -> list[StoredEvent]:
        """Messages journalled between two unix times (inclusive), only the unacknowledged ones when
        ``unacked``, only event ``event_id``'s when given, oldest first, at most ``limit`` (the newest ``limit``
        when more match)."""
        return self._select(Selection(since=since, until=until, event_id=event_id, unacked=unacked), limit)

    def get(self, event_id: str) -> list[StoredEvent]:
        """All messages of one event, oldest first."""
        return self._select(Selection(event_id=event_id), None)

    def _select(self, selection: Selection, limit: int | None) -> list[StoredEvent]:
        with self._lock:
            found: dict[tuple[str, str], StoredEvent] = {}
            if self._db is None:
                if self._readonly:
                    raise JournalError(f"the event journal {self.path} is closed")
                # opened to read only: what waits in memory is merged below and written by the next write or
                # retry(); a write that fails here (a full disk, a lock held by another process) would close the
                # file again and hide every message on it (not republished, not restored)
                self._open()
            if self._db is not None:
                try:
                    for item in rows.select(self._db, selection, self._unreadable):
                        found[item.key] = item
                except sqlite3.DatabaseError as exc:
                    if self._readonly:
                        raise JournalError(jfile.read_error(self.path, exc)) from exc
                    self._fail("cannot read the event journal", exc)
            elif not self._readonly:
                for item in self._snapshot(selection):
                    found[item.key] = item
            if self._pending_marks:              # an acknowledgement not yet on the file is one all the same
                found = {key: marked for key, item in found.items() if selection.matches(marked := self._marked(item))}
            for key, item in self._pending.items():
                if selection.matches(item):
                    found[key] = item
        out = sorted(found.values(), key=lambda s: (s.wall, s.event.t_detect))
        if limit is not None and limit >= 0:
            out = out[-limit:] if limit else []
        return out

    def _snapshot(self, selection: Selection) -> list[StoredEvent]:
        """The file cannot be opened (a read-only or full state directory): what it holds, read from a copy, so
        the messages on it are still republished and the falls on it restored. Copied again only when the file
        changed."""
        try:
            stamp = tuple((f.stat().st_mtime_ns, f.stat().st_size) if f.exists() else None
                          for f in (self.path, Path(f"{self.path}-wal")))
        except OSError:
            return []
        if stamp[0] is None:
            return []
        if self._snapshot_of is None or self._snapshot_of[0] != stamp:
            try:
                found = jfile.snapshot_rows(self.path, "1", ())
            except (OSError, sqlite3.Error) as exc:
                self._snapshot_of = (stamp, [])
                self._log.error("journal_unreadable", error=f"{type(exc).__name__}: {exc}",
                                note="the messages on the journal's file are neither republished nor restored "
                                     "until it can be read", fix=jfile.write_hint(exc))
                return []
            self._snapshot_of = (stamp, list(rows.readable(found, self._unreadable)))
        return [item for item in self._snapshot_of[1] if selection.matches(item)]

    def _marked(self, item: StoredEvent) -> StoredEvent:
        """``item`` as read from the file, with the delivery marks that wait in memory to be written on it."""
        for event_id, state, column, when, extra in self._pending_marks:
            if item.event.id == event_id and state in (None, item.event.state) and getattr(item, column) is None:
                item = replace(item, **{column: when}, **extra)
        return item

    def _unreadable(self, rowid: int, exc: Exception) -> None:
        """A row that is not a message: skipped by every read, said once (the file is kept as it is)."""
        if rowid in self.unreadable_rows or self._readonly:
            self.unreadable_rows.setdefault(rowid, str(exc))
            return
        self.unreadable_rows[rowid] = str(exc)
        self._log.error("journal_row_unreadable", rowid=rowid, error=f"{type(exc).__name__}: {exc}",
                        unreadable_rows=len(self.unreadable_rows),
                        note="this row of the event journal is not a fall-event message; it is skipped (not "
                             "republished, not handed to the hooks, not restored) and the other rows are used",
                        fix=f"look at it: sqlite3 {self.path} 'SELECT * FROM messages WHERE rowid = {rowid}'; "
                            "delete it when it is garbage (stop posed first)")

    def close(self) -> None:
        with self._lock:
            if not self._readonly:
                if self._db is None:
                    self._open()
                self._flush()
                self._sync_fallback()
            self._close_db()

    def __enter__(self) -> EventJournal:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
