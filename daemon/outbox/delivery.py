"""Delivering fall events: on disk first, then published, then the hooks; published again until acknowledged.

For each new message :meth:`EventOutbox.post` appends it to the journal (fsync'd) *before* publishing it,
then hands the stored message to the hooks (their own threads). Messages that could not be published (no
session) go out when the session opens; unacknowledged ones are published again when a subscriber appears
and every ``zenoh.event_republish_s`` while one is there. A receiver acknowledges an event by its id (every
message so far), or one message by its id and state; the rest is still republished. Acknowledgements are
counted (``accepted``, ``unknown``: no such unacknowledged message) and an unknown one is logged with a rate
limit, since anyone on the bus can send them.

The outbox publishes through a ``send(obj) -> bool`` callable (False: no session, nothing sent), so it knows
nothing of Zenoh. Times are seconds on the monotonic clock.

Hook delivery is durable, at least once. The outbox listens to the hooks (:class:`HookRunner`'s ``listener``)
and writes to the journal each hook's runs as they start (``hook_runs.attempts``) and how each hook finished
(``ok``, ``gave_up``); once every hook is done with a message, the message's ``hooks_done_at`` and
``hooks_outcome``. A run cut off by a kill -9 or a shutdown, or a message that waited in a queue then, is not
done. When the outbox is made (the publisher's start, also its restart by the supervisor after a crash), the
messages whose hooks are not done are handed to the hooks that are not done with them, in the original order
(oldest first), their attempt numbers going on from the runs already started (:meth:`EventOutbox.redeliver`).
What is too old for that is skipped, logged and marked done:

* an ``alarm`` is handed again whatever its age: it says someone has been on the floor without getting up, and
  a hook that never confirmed it (the carer's phone call) is the very failure posed exists to prevent; late,
  with its own time (``POSED_EVENT_WALL_TIME``, ``time_unix``), is better than never;
* ``falling``, ``on_floor`` and ``recovered`` only when journalled less than
  :data:`~daemon.outbox.journal_rows.REDELIVER_MAX_AGE_S` (one hour) before the start: that covers any restart
  of the daemon (a crash, an upgrade, a reboot: seconds to minutes) with a wide margin and the time in which a
  fall is still an unfolding situation someone can act on; beyond it such a message only tells of the past
  (``stale``; the fall's ``alarm``, if it came, is handed again anyway);
* at most :data:`REDELIVER_MAX_MESSAGES` messages at one start, the newest: an older backlog is marked
  ``stale`` and named in one error line (``hook_redelivery_backlog``), so a hook cut off for a week does not
  phone a carer thousands of times, nor hold up the start with a write per message.

A message handed again waits behind none of the new ones: each hook runs the detector's new messages before the
redelivered ones (:meth:`HookRunner.submit`), so a fall now is not phoned in after the backlog of the last run.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from posed.daemon import clock
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.outbox.journal_rows import REDELIVER_MAX_AGE_S
from posed.daemon.proc.throttle import Throttle, shown
from posed.falls.event import FallEvent

REDELIVERED_AT_ANY_AGE = ("alarm",)    # states handed to the hooks again at a start whatever their age
LOG_EACH_SKIPPED = 20                   # skipped messages logged one by one at a start; the rest are counted
REDELIVER_MAX_MESSAGES = 20
# At most this many messages are handed to the hooks again at one start: the newest. A backlog beyond it (a hook
# cut off or dropped from a full queue day after day, a journal whose marks could not be written for a week) is
# a fault to look at, not thousands of phone calls to a carer; the older ones are marked done (``stale``),
# named in one error line, and stay in the journal, republished on the bus until acknowledged.


@dataclass
class _HooksOf:
    """The hooks not yet done with one message, in this run of the publisher."""

    remaining: set[int]
    outcome: str = "ok"                 # gave_up once one hook gave up
    incomplete: bool = False            # a hook left it pending (shutdown, full queue): not done


class EventOutbox:
    """The journal, the hooks and the republishing schedule of the publisher stage.

    Made at the publisher's start: it hands the messages whose hooks were not done to them again
    (:meth:`redeliver`; what it did is in ``redelivery``)."""

    def __init__(self, journal: EventJournal, hooks: HookRunner, send: Callable[[dict], bool], log,
                 republish_s: float, now: float | None = None) -> None:
        self.journal = journal
        self.hooks = hooks
        self.log = log
        self.republish_s = republish_s
        self.published = 0                       # messages sent, republications included
        self._send = send
        self.acks = {"accepted": 0, "unknown": 0}
        self._throttle = Throttle()
        self._next_republish = (clock.now() if now is None else now) + republish_s
        self._hooks_lock = threading.Lock()
        self._hooks_of: dict[tuple[str, str], _HooksOf] = {}
        hooks.listener = self
        self.redelivery = self.redeliver()

    def post(self, event: FallEvent) -> FallEvent:
        """A new message from the detector: journal, publish, hooks (in that order); returns the stored
        message (with ``wall_time``)."""
        keys = self.hooks.keys
        stored = self.journal.append(event, hooks_outcome=None if keys else "no_hooks")   # on disk first
        self.log.info("fall_event", id=stored.id, state=stored.state, t_detect=stored.t_detect,
                      confidence=round(stored.confidence, 3), features=list(stored.features))
        self.publish([stored], "new")
        if keys:
            self._follow(stored, set(range(len(keys))))
        self.hooks.submit(stored)
        return stored

    # ---------------------------------------------------------------- hook delivery

    def redeliver(self) -> dict:
        """Hand the messages whose hooks are not done to the hooks not done with them, oldest first (see the
        module docstring for what is skipped; at most :data:`REDELIVER_MAX_MESSAGES`, the newest). Returns the
        counts (``redelivered``, ``stale``, ``backlog``: stale for being beyond that bound, ``no_hooks``,
        ``finished``: every hook had finished but the message was not marked so)."""
        counts = {"redelivered": 0, "stale": 0, "backlog": 0, "no_hooks": 0, "finished": 0}
        pending = self.journal.hooks_pending()
        if not pending:
            return counts
        keys = self.hooks.keys
        now = self.journal.wall_now()
        done: dict[str, list[tuple[str, str]]] = {}       # outcome -> messages marked so, in one write each
        wanted = []
        for stored, runs in pending:
            e, age = stored.event, now - stored.wall
            skip = self._skip(e, age, keys)
            if skip is not None:
                outcome, why = skip
                counts[outcome] += 1
                if counts["stale"] + counts["no_hooks"] <= LOG_EACH_SKIPPED:
                    self.log.warning("hook_redelivery_skipped", id=e.id, state=e.state, age_s=round(age, 1),
                                     wall_time=e.wall_time, outcome=outcome, reason=why,
                                     note="its hooks were not done with it when the publisher last stopped; it is "
                                          "marked done and will not be handed to them")
                done.setdefault(outcome, []).append(stored.key)
                continue
            attempts, outcome = {}, "ok"
            for i, key in enumerate(keys):
                run = runs.get(key)
                if run is not None and run.outcome is not None:          # this hook finished with it
                    outcome = "gave_up" if run.outcome == "gave_up" else outcome
                    continue
                attempts[i] = (run.attempts if run is not None else 0) + 1
            if not attempts:                    # every hook finished; the stop came before the message's mark
                counts["finished"] += 1
                done.setdefault(outcome, []).append(stored.key)
                continue
            wanted.append((stored, attempts, outcome, age))
        skipped = counts["stale"] + counts["no_hooks"]
        if skipped > LOG_EACH_SKIPPED:
            self.log.warning("hook_redelivery_skipped_more", count=skipped - LOG_EACH_SKIPPED,
                             stale=counts["stale"], no_hooks=counts["no_hooks"])
        backlog, wanted = wanted[:-REDELIVER_MAX_MESSAGES], wanted[-REDELIVER_MAX_MESSAGES:]
        if backlog:
            counts["backlog"] = len(backlog)
            done.setdefault("stale", []).extend(stored.key for stored, *_ in backlog)
            self._log_backlog(backlog)
        for outcome, messages in done.items():
            self.journal.mark_hooks_done_many(messages, outcome)
        handed = []
        for stored, attempts, outcome, age in wanted:
            e = stored.event
            self._follow(e, set(attempts), outcome)
            self.hooks.submit(e, attempts=attempts, redelivered=True)
            counts["redelivered"] += 1
            handed.append({"id": e.id, "state": e.state, "age_s": round(age, 1), "hooks": sorted(attempts),
                           "attempt": max(attempts.values())})
        if handed:
            self.log.warning("hooks_redelivered", count=len(handed), messages=handed[:LOG_EACH_SKIPPED],
                             note="the hooks were not done with these messages when the publisher last stopped "
                                  "(killed, crashed or stopped with runs cut off or waiting); they run again, "
                                  "oldest first (POSED_HOOK_REDELIVERED=1)")
        return counts

    def _log_backlog(self, backlog: list) -> None:
        alarms = [stored for stored, *_ in backlog if stored.event.state == "alarm"]
        oldest, newest = backlog[0][0], backlog[-1][0]
        self.log.error("hook_redelivery_backlog", count=len(backlog), alarms=len(alarms),
                       oldest=oldest.event.wall_time, newest=newest.event.wall_time,
                       ids=[f"{s.event.id}:{s.event.state}" for s, *_ in backlog[-LOG_EACH_SKIPPED:]],
                       redelivered_max=REDELIVER_MAX_MESSAGES,
                       note=f"more messages than {REDELIVER_MAX_MESSAGES} wait for the hooks: only the newest are "
                            "handed to them again; these older ones are marked done (stale) and stay in the "
                            "journal, republished on the bus until acknowledged",
                       fix="find why the hooks were cut off or dropped for so long (hook_queue_full, "
                           "hook_ended_at_shutdown, journal_unavailable in the log); look at these events with "
                           "posed events --since 30d and acknowledge them")

    @staticmethod
    def _skip(e: FallEvent, age: float, keys) -> tuple[str, str] | None:
        """(outcome, why) when a message whose hooks are not done is not handed to them again at a start."""
        if not keys:
            return "no_hooks", "no hook is configured now"
        if e.state not in REDELIVERED_AT_ANY_AGE and age > REDELIVER_MAX_AGE_S:
            return "stale", (f"journalled {age:.0f} s ago, more than {REDELIVER_MAX_AGE_S:g} s: a {e.state} message "
                             "that old tells of the past (an alarm is handed again at any age)")
        return None

    def _follow(self, e: FallEvent, hooks: set[int], outcome: str = "ok") -> None:
        with self._hooks_lock:
            self._hooks_of[(e.id, e.state)] = _HooksOf(set(hooks), outcome)

    def hook_starting(self, event: FallEvent, hook: int, attempt: int) -> None:
        """(HookListener, a hook's thread) on disk before the run starts: a restart goes on from ``attempt``."""
        self.journal.hook_started(event.id, event.state, self.hooks.keys[hook], attempt)

    def hook_ended(self, event: FallEvent, hook: int, outcome: str) -> None:
        """(HookListener, a hook's thread) ``ok`` or ``gave_up``: that hook is done with the message, which is
        done once every hook is; ``pending``: not done (handed again at the next start)."""
        if outcome in ("ok", "gave_up"):
            self.journal.hook_finished(event.id, event.state, self.hooks.keys[hook], outcome)
        key = (event.id, event.state)
        with self._hooks_lock:
            followed = self._hooks_of.get(key)
            if followed is None or hook not in followed.remaining:
                return
            followed.remaining.discard(hook)
            if outcome == "gave_up":
                followed.outcome = "gave_up"
            elif outcome != "ok":
                followed.incomplete = True
            if followed.remaining:
                return
            del self._hooks_of[key]
            if followed.incomplete:
                return
        self.journal.mark_hooks_done(event.id, event.state, followed.outcome)

    def publish(self, events: Iterable[FallEvent], why: str) -> int:
        """Send ``events`` and mark them published; stops at the first that cannot be sent. Returns how many
        went out; a republication (``why`` other than "new") is logged."""
        n = 0
        for event in events:
            if not self._send(event.to_json()):
                break
            self.journal.mark_published(event.id, event.state)
            self.published += 1
            n += 1
        if n and why != "new":
            self.log.info("fall_events_republished", count=n, reason=why)
        return n

    def session_opened(self) -> int:
        """The session (re)opened: publish what was journalled while it was closed."""
        return self.publish(self.journal.unpublished(), "unpublished")

    def subscriber_appeared(self, now: float) -> int:
        """Someone subscribed to the events: publish every unacknowledged message now (and restart the
        period)."""
        self._next_republish = now + self.republish_s
        return self.publish(self.journal.unacknowledged(), "subscriber appeared")

    def tick(self, now: float, subscribed: bool) -> None:
        """Every ``republish_s``: retry writing what waits in memory and, when someone is subscribed, publish
        the unacknowledged messages again."""
        if now < self._next_republish:
            return
        self._next_republish = now + self.republish_s
        self.journal.retry()
        if subscribed:
            self.publish(self.journal.unacknowledged(), "period")

    def acknowledge(self, event_id: str, state: str | None = None, by: str | None = None) -> int:
        """A receiver acknowledged ``event_id``: all its messages so far, or only the one of ``state``; ``by``:
        who (free text, kept in the journal as ``acked_by``). Returns how many (called on a Zenoh thread: the
        journal is thread-safe). ``event_id`` is bounded (:mod:`daemon.bus.acks`) and shortened in the log line."""
        n = self.journal.acknowledge(event_id, state, by)
        if n:
            self.acks["accepted"] += 1
            self.log.info("fall_event_acknowledged", id=shown(event_id), state=state, by=by, messages=n)
            return n
        self.acks["unknown"] += 1
        suppressed = self._throttle.allow("unknown")
        if suppressed is not None:
            self.log.warning("ack_of_unknown_event", id=shown(event_id), state=state, unknown=self.acks["unknown"],
                             suppressed=suppressed, note="no unacknowledged message has this id (and state)")
        return 0

    def status(self) -> dict:
        """The ``events`` part of the status object."""
        journal = self.journal
        return {"unacknowledged": len(journal.unacknowledged()),
                "journal": "ok" if journal.healthy else (journal.last_error or "degraded"),
                "published": self.published, "acks": dict(self.acks)}

    def close(self, hook_timeout_s: float = 1.0) -> None:
        """Give the hooks ``hook_timeout_s`` to finish, then write and close the journal."""
        self.hooks.close(timeout=hook_timeout_s)
        self.journal.close()
