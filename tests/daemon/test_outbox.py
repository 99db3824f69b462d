"""The event outbox: journal before publish before hooks, what waited goes out when the session opens,
republishing on a new subscriber and on the period, acknowledgement, status."""

from __future__ import annotations

from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.journal import EventJournal
from posed.falls.event import FallEvent
from tests.daemon.fakes import RecordingLog


def event(state="falling", id_="e1", t=10.0) -> FallEvent:
    return FallEvent(id=id_, robot="r1", state=state, t_onset=t - 1.0, t_impact=t - 0.4, t_detect=t,
                     confidence=0.8, features=("pelvis_descent_fast",))


class Bus:
    """A send callable that notes, for each message, whether it was already in the journal."""

    def __init__(self, journal: EventJournal) -> None:
        self.journal = journal
        self.open = True
        self.sent: list[tuple[str, str, bool]] = []

    def __call__(self, obj: dict) -> bool:
        if not self.open:
            return False
        on_disk = any(s.event.state == obj["state"] for s in self.journal.get(obj["id"]))
        self.sent.append((obj["id"], obj["state"], on_disk))
        return True


class Hooks:
    """Records what it is handed (no hook configured: ``keys`` is empty, as HookRunner's with none)."""

    keys: tuple[str, ...] = ()

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.got: list[tuple[str, str, int]] = []
        self.closed = False

    def submit(self, e: FallEvent, attempts=None, redelivered=False) -> None:
        self.got.append((e.id, e.state, len(self.bus.sent)))

    def close(self, timeout: float) -> None:
        self.closed = True


def outbox(tmp_path, republish_s=30.0):
    journal = EventJournal(tmp_path / "events.sqlite3")
    bus = Bus(journal)
    hooks = Hooks(bus)
    log = RecordingLog()
    return EventOutbox(journal, hooks, bus, log, republish_s, now=0.0), bus, hooks, log


def test_journal_then_publish_then_hooks(tmp_path):
    box, bus, hooks, log = outbox(tmp_path)
    stored = box.post(event())
    assert stored.wall_time                                           # the journal's copy
    assert bus.sent == [("e1", "falling", True)]                      # on disk before it was sent
    assert hooks.got == [("e1", "falling", 1)]                        # the hooks after the publication
    assert box.journal.unpublished() == [] and box.published == 1
    assert log.events() == ["fall_event"]
    box.close()
    assert hooks.closed


def test_without_a_session_events_wait_and_go_out_when_it_opens(tmp_path):
    box, bus, hooks, log = outbox(tmp_path)
    bus.open = False
    box.post(event())
    box.post(event("alarm"))
    assert bus.sent == [] and len(hooks.got) == 2                     # hooks run anyway
    assert [e.state for e in box.journal.unpublished()] == ["falling", "alarm"]
    bus.open = True
    assert box.session_opened() == 2
    assert [s for _, s, _ in bus.sent] == ["falling", "alarm"] and box.journal.unpublished() == []
    assert ("info", "fall_events_republished", {"count": 2, "reason": "unpublished"}) in log.lines
    assert box.session_opened() == 0


def test_republished_until_acknowledged(tmp_path):
    box, bus, hooks, log = outbox(tmp_path, republish_s=30.0)
    box.post(event())
    box.post(event("falling", id_="e2"))
    bus.sent.clear()
    assert box.subscriber_appeared(5.0) == 2
    box.tick(30.0, subscribed=True)                                   # the period restarted at 5 s
    assert len(bus.sent) == 2
    box.tick(35.0, subscribed=True)
    assert len(bus.sent) == 4
    box.tick(65.0, subscribed=False)                                  # nobody listens: not sent
    assert len(bus.sent) == 4
    assert box.acknowledge("e1") == 1
    assert ("info", "fall_event_acknowledged", {"id": "e1", "state": None, "by": None, "messages": 1}) in log.lines
    box.tick(95.0, subscribed=True)
    assert [i for i, _, _ in bus.sent[4:]] == ["e2"]
    reasons = [f["reason"] for lv, e, f in log.lines if e == "fall_events_republished"]
    assert reasons == ["subscriber appeared", "period", "period"]
    assert box.status() == {"unacknowledged": 1, "journal": "ok", "published": 7,
                            "acks": {"accepted": 1, "unknown": 0}}
