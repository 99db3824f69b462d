"""A history query that names an event (``posed/ROBOT/events/history/<id>/**``) gets that event's messages however
old, and every reply lies within the keys asked (Zenoh refuses a reply outside them: before, such a query got an
error after the first other event's message). The client's ``ack(confirm_s=...)`` reads the event it acknowledged
by its id, so an alarm older than the newest ``HISTORY_LIMIT`` messages (a robot back from days offline, a carer
acknowledging last week's alarm) is confirmed. Real journal, real outbox, the daemon's real bus link on a real
Zenoh session on 127.0.0.1 (scouting off), a real client session."""

from __future__ import annotations

import contextlib

from posed.client import PosedClient
from posed.client import api as client_api
from posed.daemon.bus.link import BusLink
from posed.daemon.config.sections import HooksConfig, ZenohConfig
from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.falls.event import FallEvent
from tests.daemon import zenoh_util
from tests.daemon.fakes import RecordingLog

STATES = ("falling", "on_floor", "alarm")


def message(id_: str, state: str, t: float) -> FallEvent:
    return FallEvent(id=id_, robot="r1", state=state, t_onset=t - 1.0, t_impact=t - 0.4, t_detect=t,
                     confidence=0.8, features=("pelvis_descent_fast",))


def test_one_event_is_read_by_its_id_and_its_old_alarm_confirmed(tmp_path, monkeypatch):
    journal = EventJournal(tmp_path / "events.sqlite3")
    log = RecordingLog()
    box = EventOutbox(journal, HookRunner(HooksConfig()), lambda obj: True, log, 30.0)
    for n in range(6):                                   # e0 is the oldest fall; e1..e5 came after it
        for k, state in enumerate(STATES):
            box.post(message(f"e{n}", state, 100.0 * n + k))
    endpoint = f"tcp/127.0.0.1:{zenoh_util.free_port()}"

    def lookup(since, until, limit, event_id=None):      # the publisher stage's (daemon/stages/publish.py)
        return journal.query(since, until, limit, event_id=event_id)

    with contextlib.ExitStack() as stack:
        link = BusLink(ZenohConfig(listen=(endpoint,)), "r1", stack, log, history=lookup,
                       on_ack=lambda event_id, state, by: box.acknowledge(event_id, state, by))
        assert link.try_open(0.0)
        session = stack.enter_context(zenoh_util.client(endpoint))
        c = PosedClient(session)

        old = c.history("r1", event_id="e0", limit=10)
        assert [(h.event.id, h.event.state) for h in old] == [("e0", s) for s in STATES]
        assert [h.event.state for h in c.history("r1", event_id="e0", limit=1)] == ["alarm"]   # its newest

        replies = session.get("posed/r1/events/history/*/alarm?limit=100", timeout=5.0)
        keys = sorted(str(r.ok.key_expr) for r in replies if r.ok is not None)
        assert keys == [f"posed/r1/events/history/e{n}/alarm" for n in range(6)]
        assert "history_query_failed" not in log.events("warning")

        # the carer acknowledges e0's alarm; the client confirms it from e0's own messages, though e0 is
        # not among the newest HISTORY_LIMIT (here 6) messages the client read before
        monkeypatch.setattr(client_api, "HISTORY_LIMIT", 6)
        assert c.ack("r1", "e0", "alarm", by="daughter", confirm_s=10.0) is True
        acked = {(s.event.id, s.event.state): s.acked_by for s in journal.query()}
        assert acked[("e0", "alarm")] == "daughter" and acked[("e5", "alarm")] is None
    box.close()
