"""An acknowledgement's ``by`` (docs/formats.md ``posed.ack``): parsed and bounded, carried from the bus link
through the publisher's ``on_ack(id, state, by)`` to the outbox, kept in the real journal (``acked_by``, the first
acknowledgement's), logged in ``fall_event_acknowledged``, answered in history replies (schema-valid, read by the
client's HistoryEntry) and shown by ``posed events``; ``posed events ack --by``. Acks without ``by`` still work.
Over real Zenoh against the real daemon: tests/daemon/test_hook_redelivery_e2e.py."""

from __future__ import annotations

import contextlib
import json
import re

import pytest

from posed.cli import main
from posed.client import HistoryEntry, contract
from posed.commands.events import default_by
from posed.daemon.bus import queries
from posed.daemon.bus.acks import MAX_BY_CHARS, BadAck, parse_ack_message
from posed.daemon.bus.link import BusLink
from posed.daemon.config.sections import HooksConfig, ZenohConfig
from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.falls.event import FallEvent
from tests.daemon.fakes import FakeQuery, RecordingLog, sample


def message(state: str, id_: str = "e1", t: float = 10.0) -> FallEvent:
    return FallEvent(id=id_, robot="r1", state=state, t_onset=t - 1.0, t_impact=t - 0.4, t_detect=t,
                     confidence=0.8, features=("pelvis_descent_fast",))


def test_by_is_parsed_and_bounded():
    assert parse_ack_message(b'{"id": "e1", "by": " daughter "}').by == "daughter"
    ack = parse_ack_message(b'{"id": "e1", "state": "alarm", "by": "Dr. Anna K\xc3\xbchn"}')
    assert (ack.id, ack.state, ack.by) == ("e1", "alarm", "Dr. Anna Kühn")
    for payload in (b"e1", b'{"id": "e1"}', b'{"id": "e1", "by": null}', b'{"id": "e1", "by": "  "}'):
        ack = parse_ack_message(payload)
        assert ack.id == "e1" and ack.by is None
    assert type(str(parse_ack_message(b'{"id": "e1", "by": "x"}').id)) is str
    for payload, why in ((b'{"id": "e1", "by": 7}', "must be text"),
                         (json.dumps({"id": "e1", "by": "x" * (MAX_BY_CHARS + 1)}).encode(), "too long"),
                         (b'{"id": "e1", "by": "a\\u0000b"}', "control characters")):
        with pytest.raises(BadAck, match=why):
            parse_ack_message(payload)


def test_by_goes_from_the_bus_link_to_the_journal_the_log_and_the_history(tmp_path):
    journal = EventJournal(tmp_path / "events.sqlite3")
    log = RecordingLog()
    box = EventOutbox(journal, HookRunner(HooksConfig()), lambda obj: True, log, 30.0)
    for state in ("falling", "on_floor", "alarm"):
        box.post(message(state))
    box.post(message("falling", "e2"))
    with contextlib.ExitStack() as stack:
        # the publisher stage wires on_ack to ``outbox.acknowledge(event_id, state, by)``
        link = BusLink(ZenohConfig(), "r1", stack, log, history=lambda *a: [],
                       on_ack=lambda event_id, state, by: box.acknowledge(event_id, state, by))
        link._on_ack_sample(sample(json.dumps({"id": "e1", "state": "alarm", "by": "daughter"})))
        link._on_ack_sample(sample(json.dumps({"id": "e1", "by": "night nurse"})))     # the rest of e1
        link._on_ack_sample(sample("e2"))                                                # a bare id: no by
        link._on_ack_sample(sample(json.dumps({"id": "e2", "by": "too late"})))          # nothing left: unknown
    acked = [f for _, e, f in log.lines if e == "fall_event_acknowledged"]
    assert acked == [{"id": "e1", "state": "alarm", "by": "daughter", "messages": 1},
                     {"id": "e1", "state": None, "by": "night nurse", "messages": 2},
                     {"id": "e2", "state": None, "by": None, "messages": 1}]
    by = {s.key: s.acked_by for s in journal.query()}
    assert by == {("e1", "falling"): "night nurse", ("e1", "on_floor"): "night nurse", ("e1", "alarm"): "daughter",
                  ("e2", "falling"): None}                          # the first acknowledgement's is kept

    base = "posed/r1/events/history"

    def lookup(since, until, limit, event_id=None):
        return journal.query(since, until, limit, event_id=event_id)

    q = FakeQuery(f"{base}/**")
    queries.answer_history(q, base, lookup, log)
    replies = [json.loads(p) for _, p in q.replies]
    for obj in replies:
        contract.validate(obj)
    assert [(o["state"], o["acked_by"]) for o in replies] == [
        ("falling", "night nurse"), ("on_floor", "night nurse"), ("alarm", "daughter"), ("falling", None)]
    entries = [HistoryEntry.from_json(o) for o in replies]
    assert entries[2].acked_by == "daughter" and entries[2].hooks_outcome == "no_hooks"
    assert "acked_by" not in entries[2].event.extra                # delivery fields are not the event's
    bare = FakeQuery(base)
    queries.answer_history(bare, base, lookup, log)
    reply = json.loads(bare.replies[0][1])
    contract.validate(reply)
    assert [e["acked_by"] for e in reply["events"]] == ["night nurse", "night nurse", "daughter", None]
    assert HistoryEntry.from_json({k: v for k, v in replies[0].items()
                                   if k not in ("acked_by", "hooks_done_at", "hooks_outcome")}).acked_by is None
    box.close()


def test_posed_events_shows_who_acknowledged(tmp_path, capsys):
    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as journal:
        journal.append(message("falling"))
        journal.append(message("alarm"))
        journal.append(message("falling", "e2"))
        journal.acknowledge("e1", "alarm", by="daughter")
        journal.acknowledge("e2")
    assert main(["events", "--journal", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "acked by" in out[0] and "hooks" in out[0]
    rows = {(r.split()[2], r.split()[1][:2]): r for r in out[1:]}
    assert re.search(r" yes daughter +pending ", rows[("alarm", "e1")])
    assert re.search(r" no +pending ", rows[("falling", "e1")])
    assert re.search(r" yes - +pending ", rows[("falling", "e2")])         # acknowledged without a name
    assert main(["events", "--journal", str(path), "--json"]) == 0
    events = json.loads(capsys.readouterr().out)["events"]
    assert [(e["id"], e["state"], e["acked_by"]) for e in events] == [
        ("e1", "falling", None), ("e1", "alarm", "daughter"), ("e2", "falling", None)]


def test_posed_events_ack_by(tmp_path, capsys):
    user, _, host = default_by().partition("@")
    assert user and host
    assert main(["events", "ack", "e1", "--by", "x" * (MAX_BY_CHARS + 1), "--journal",
                 str(tmp_path / "none.sqlite3"), "--connect", "tcp/127.0.0.1:1", "--wait", "0.1"]) == 2
    assert f"at most {MAX_BY_CHARS}" in capsys.readouterr().err
