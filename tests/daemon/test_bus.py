"""The publisher's bus parts without a network: payloads, the query and ack handlers, and the link's session
life (per-stream QoS, declarations, retries, release) on a recording stand-in session."""

from __future__ import annotations

import contextlib
import json
import math
from types import SimpleNamespace

import pytest
import zenoh

from posed.daemon.bus import link as link_mod
from posed.daemon.bus import queries
from posed.daemon.bus.link import BusLink
from posed.daemon.bus.payloads import dumps, pose_message
from posed.daemon.bus.session import ZenohConfigError
from posed.daemon.config.sections import ZenohConfig
from posed.daemon.outbox.journal import StoredEvent
from posed.falls.event import FallEvent
from tests.daemon.fakes import FakeQuery, FakeSession, RecordingLog, sample


def stored(id_: str, state: str, wall: float) -> StoredEvent:
    ev = FallEvent(id=id_, robot="r1", state=state, t_onset=None, t_impact=1.0, t_detect=2.0, confidence=0.5)
    return StoredEvent(ev, wall, None, None)


def test_dumps_turns_non_finite_numbers_into_null():
    assert json.loads(dumps({"a": [1.0, math.nan], "b": {"c": math.inf}, "d": (2, -math.inf)})) == \
        {"a": [1.0, None], "b": {"c": None}, "d": [2, None]}
    assert dumps({"x": 1.5}) == '{"x": 1.5}'


def test_pose_message_counts_latency_from_the_origin():
    result = SimpleNamespace(to_json=lambda: {"seq": 4, "t": 10.0, "ok": True})
    msg = SimpleNamespace(result=result, t_capture=10.0, image_size=(640, 480), t_origin=10.5,
                          stamps=(("fitting_in", 10.6), ("fitting_out", 10.7)))
    out = pose_message(msg, now=11.0)
    assert out["seq"] == 4 and out["image_size"] == [640, 480]
    assert out["timing_ms"]["total"] == pytest.approx(500.0) and out["timing_ms"]["fitting"] == pytest.approx(100.0)


def test_history_parameters():
    assert queries.parse_history_parameters({}) == (None, None, queries.HISTORY_DEFAULT_LIMIT)
    assert queries.parse_history_parameters({"since": "1700000000", "until": "1700000100", "limit": "5"}) == \
        (1700000000.0, 1700000100.0, 5)
    for bad in ({"limit": "x"}, {"limit": "-1"}, {"limit": str(queries.HISTORY_MAX_LIMIT + 1)}):
        with pytest.raises(ValueError, match="limit"):
            queries.parse_history_parameters(bad)


def test_history_answers_per_message_or_as_one_list():
    base = "posed/r1/events/history"
    rows = [stored("e1", "falling", 100.0), stored("e1", "alarm", 101.0)]
    asked = []

    def lookup(since, until, limit, event_id=None):
        asked.append((since, until, limit))
        return [r for r in rows if event_id in (None, r.event.id)][-limit:]

    log = RecordingLog()
    q = FakeQuery(f"{base}/**", limit="10")
    queries.answer_history(q, base, lookup, log)
    assert [k for k, _ in q.replies] == [f"{base}/e1/falling", f"{base}/e1/alarm"]
    assert json.loads(q.replies[1][1])["state"] == "alarm" and asked == [(None, None, 10)]
    bare = FakeQuery(base, limit="1")
    queries.answer_history(bare, base, lookup, log)
    assert len(bare.replies) == 1 and json.loads(bare.replies[0][1])["count"] == 1
    bad = FakeQuery(base, limit="many")
    queries.answer_history(bad, base, lookup, log)
    assert not bad.replies and "limit" in json.loads(bad.errors[0])["error"]

    def broken(*_):
        raise RuntimeError("disk gone")

    failing = FakeQuery(base)
    queries.answer_history(failing, base, broken, log)
    assert "disk gone" in failing.errors[0] and log.events("warning") == ["history_query_failed"]


def test_history_answers_one_event_or_one_state_within_the_keys_asked():
    """A query naming an event (``<base>/<id>/**``) is looked up by its id, however old; every reply lies within
    the query's keys (Zenoh refuses one outside them: ``<base>/*/alarm`` gets the alarms only)."""
    base = "posed/r1/events/history"
    rows = [stored("e1", "falling", 100.0), stored("e1", "alarm", 101.0), stored("e2", "falling", 200.0)]
    ids = []

    def lookup(since, until, limit, event_id=None):
        ids.append(event_id)
        return [r for r in rows if event_id in (None, r.event.id)][-limit:]

    log = RecordingLog()
    one = FakeQuery(f"{base}/e1/**", limit="1")
    queries.answer_history(one, base, lookup, log)
    assert [k for k, _ in one.replies] == [f"{base}/e1/alarm"] and ids == ["e1"]      # the newest of e1's
    alarms = FakeQuery(f"{base}/*/alarm")
    queries.answer_history(alarms, base, lookup, log)
    assert [k for k, _ in alarms.replies] == [f"{base}/e1/alarm"] and ids[-1] is None
    state = FakeQuery(f"{base}/e2/falling")
    queries.answer_history(state, base, lookup, log)
    assert [k for k, _ in state.replies] == [f"{base}/e2/falling"] and ids[-1] == "e2"
    assert queries.event_of_query(f"{base}/**", base) is None and queries.event_of_query(base, base) is None
    assert log.events("warning") == []


def test_state_answers_the_latest_pose_and_status():
    latest = queries.LatestState()
    q = FakeQuery("posed/r1/state")
    queries.answer_state(q, "posed/r1/state", latest, RecordingLog())
    first = json.loads(q.replies[0][1])
    assert {k: first[k] for k in ("pose", "status", "format", "version", "robot")} == \
        {"pose": None, "status": None, "format": "posed.state", "version": 1, "robot": "r1"}
    latest.set_pose({"seq": 1, "x": math.nan})
    latest.set_status({"state": "running"})
    queries.answer_state(q, "posed/r1/state", latest, RecordingLog())
    second = json.loads(q.replies[1][1])
    assert (second["pose"], second["status"]) == ({"seq": 1, "x": None}, {"state": "running"})


@pytest.mark.parametrize("payload, expected", [("e1", "e1"), ("  e1\n", "e1"), ('{"id": "e2"}', "e2"),
                                               ('{"id": 7}', "7"), ("{not json", ""), ("[1]", "[1]"),
                                               ('{"other": 1}', ""), ("", "")])
def test_ack_payloads(payload, expected):
    assert queries.parse_ack(payload) == expected


@pytest.fixture
def fake_zenoh(monkeypatch):
    sessions: list[FakeSession] = []
    failures: list[Exception] = []

    def open_session(cfg):
        if failures:
            raise failures.pop(0)
        sessions.append(FakeSession())
        return sessions[-1]

    monkeypatch.setattr(link_mod, "open_session", open_session)
    return sessions, failures


def test_link_declares_each_stream_with_its_qos_and_releases_them(fake_zenoh):
    sessions, _ = fake_zenoh
    acks, log = [], RecordingLog()
    with contextlib.ExitStack() as stack:
        link = BusLink(ZenohConfig(), "r1", stack, log, history=lambda *a: [],
                       on_ack=lambda i, st, by: acks.append(i))
        assert link.put_pose({"seq": 0}) is False and not link.wants_landmarks     # no session yet: dropped
        assert link.try_open(0.0) is True and link.try_open(1.0) is False
        s = sessions[0]
        e = s.entities
        pose, fall = e["posed/r1/pose"].options, e["posed/r1/events/fall"].options
        assert pose["congestion_control"] == zenoh.CongestionControl.DROP and pose["express"] is True
        assert pose["priority"] == zenoh.Priority.DATA_HIGH
        for key in ("posed/r1/landmarks", "posed/r1/status"):
            assert e[key].options["congestion_control"] == zenoh.CongestionControl.DROP
        assert fall["congestion_control"] == zenoh.CongestionControl.BLOCK
        assert fall["reliability"] == zenoh.Reliability.RELIABLE
        assert fall["priority"] == zenoh.Priority.INTERACTIVE_HIGH
        assert e["posed/r1/alive"].kind == "token"
        assert [k for k, x in e.items() if x.kind == "token" and k.startswith("posed/r1/alive/fake-zid.")]
        assert e["posed/r1/alive/*"].kind == "liveliness_subscriber" and e["posed/r1/alive/*"].options["history"]
        assert e["posed/r1/state"].kind == "queryable" and e["posed/r1/state"].options == {"complete": True}
        assert e["posed/r1/events/history/**"].kind == "queryable"
        assert link.put_pose({"seq": 1}) and link.wants_landmarks and link.put_event({"id": "e1"})
        assert e["posed/r1/pose"].sent == ['{"seq": 1}'] and e["posed/r1/events/fall"].sent == ['{"id": "e1"}']
        assert link.latest.snapshot()["pose"] == {"seq": 1}
        assert link.status() == {"session": "open", "mode": "peer", "listen": ["tcp/127.0.0.1:7447"],
                                 "connect": [], "error": None, "robot_id_conflict": None, "peers": 2, "routers": 0}
        ack = e["posed/r1/events/ack"].callback
        ack(sample('{"id": "e1"}'))
        ack(sample("   "))
        assert acks == ["e1"] and log.events("warning") == ["bad_ack"]
        q = FakeQuery("posed/r1/state")
        e["posed/r1/state"].callback(q)
        assert json.loads(q.replies[0][1])["pose"] == {"seq": 1}
    assert all(x.undeclared for x in e.values()) and s.closed
    assert link.put_event({"id": "e2"}) is False                   # released: nothing is sent any more


def test_link_notices_a_subscriber_appearing(fake_zenoh):
    with contextlib.ExitStack() as stack:
        link = BusLink(ZenohConfig(), "r1", stack, RecordingLog(), history=lambda *a: [], on_ack=print)
        assert link.event_subscriber_appeared(0.0) is False              # no session
        link.try_open(0.0)
        fall = fake_zenoh[0][0].entities["posed/r1/events/fall"]
        assert link.event_subscriber_appeared(0.0) is False and not link.event_subscribed
        fall.matching_status.matching = True
        assert link.event_subscriber_appeared(0.1) is False              # not polled again before MATCH_POLL_S
        assert link.event_subscriber_appeared(link_mod.MATCH_POLL_S) is True and link.event_subscribed
        assert link.event_subscriber_appeared(2 * link_mod.MATCH_POLL_S) is False     # still there: no edge
        fall.matching_status.matching = False
        assert link.event_subscriber_appeared(3 * link_mod.MATCH_POLL_S) is False and not link.event_subscribed


def test_link_retries_opening_and_says_why(fake_zenoh):
    sessions, failures = fake_zenoh
    failures.extend([RuntimeError("Unable to connect to tcp/127.0.0.1:1")] * 12)
    log = RecordingLog()
    cfg = ZenohConfig(mode="client", connect=("tcp/127.0.0.1:1",), reconnect_s=2.0)
    with contextlib.ExitStack() as stack:
        link = BusLink(cfg, "r1", stack, log, history=lambda *a: [], on_ack=print)
        assert link.try_open(0.0) is False
        assert link.status()["session"] == "retrying" and "cannot reach" in link.status()["error"]
        assert link.try_open(1.0) is False and len(failures) == 11       # too early to try again
        for i in range(1, 12):
            link.try_open(2.0 * i)
        assert log.events("error") == ["zenoh_unavailable", "zenoh_unavailable"]     # the 1st and the 12th
        assert link.try_open(24.0) is True and link.status()["error"] is None and len(sessions) == 1
    failures.append(ZenohConfigError("zenoh.config_file: bad"))
    with contextlib.ExitStack() as stack:
        link = BusLink(cfg, "r1", stack, log, history=lambda *a: [], on_ack=print)
        with pytest.raises(ZenohConfigError):
            link.try_open(0.0)
