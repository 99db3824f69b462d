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
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from posed.daemon import clock
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.proc.throttle import Throttle, shown
from posed.falls.event import FallEvent


class EventOutbox:
    """The journal, the hooks and the republishing schedule of the publisher stage."""

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

    def post(self, event: FallEvent) -> FallEvent:
        """A new message from the detector: journal, publish, hooks (in that order); returns the stored
        message (with ``wall_time``)."""
        stored = self.journal.append(event)          # on disk before anyone hears of it
        self.log.info("fall_event", id=stored.id, state=stored.state, t_detect=stored.t_detect,
                      confidence=round(stored.confidence, 3), features=list(stored.features))
        self.publish([stored], "new")
        self.hooks.submit(stored)
        return stored

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

    def acknowledge(self, event_id: str, state: str | None = None) -> int:
        """A receiver acknowledged ``event_id``: all its messages so far, or only the one of ``state``.
        Returns how many (called on a Zenoh thread: the journal is thread-safe). ``event_id`` is bounded
        (:mod:`daemon.bus.acks`) and shortened in the log line."""
        n = self.journal.acknowledge(event_id, state)
        if n:
            self.acks["accepted"] += 1
            self.log.info("fall_event_acknowledged", id=shown(event_id), state=state, messages=n)
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
