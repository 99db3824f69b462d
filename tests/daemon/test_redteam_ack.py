"""The ack key under attack and in ordinary use, on the real publisher over real Zenoh on 127.0.0.1: a
state-specific acknowledgement acknowledges only that state (the others are still republished), and a flood
of 20,000 bad, unknown, oversized and non-UTF-8 acknowledgements is counted, not written line by line."""

from __future__ import annotations

import json
import sqlite3

import pytest
import zenoh

from tests.daemon.redteam_util import publisher_daemon, until
from tests.daemon.zenoh_util import client


def _collect(session, key):
    got = []
    sub = session.declare_subscriber(key, lambda s: got.append(json.loads(s.payload.to_string())))
    return got, sub


def _acked(db_path) -> dict[str, bool]:
    with sqlite3.connect(db_path) as db:
        return {state: acked is not None for state, acked in db.execute("SELECT state, acked_at FROM messages")}


def test_state_ack_acknowledges_only_that_state_and_the_rest_is_republished(tmp_path):
    h, ep = publisher_daemon(tmp_path)
    db_path = tmp_path / "state" / "events.sqlite3"
    try:
        with client(ep) as s:
            statuses, _s = _collect(s, "posed/r7/status")
            until(lambda: statuses and statuses[-1]["events"]["unacknowledged"] >= 3, 30, "three fall messages")
            with sqlite3.connect(db_path) as db:
                (event_id,) = {r[0] for r in db.execute("SELECT event_id FROM messages")}
            states = set(_acked(db_path))
            assert {"falling", "on_floor", "alarm"} <= states
            s.put("posed/r7/events/ack", json.dumps({"id": event_id, "state": "alarm"}))
            until(lambda: _acked(db_path)["alarm"], 10, "the alarm acknowledged")
            acked = _acked(db_path)
            assert acked["falling"] is False and acked["on_floor"] is False, acked
            # a receiver appears: what it has not acknowledged is published again, the alarm is not
            events, _e = _collect(s, "posed/r7/events/fall")
            until(lambda: {e["state"] for e in events} >= {"falling", "on_floor"}, 10, "republished messages")
            assert "alarm" not in {e["state"] for e in events}
            # an ack without a state acknowledges the whole event
            s.put("posed/r7/events/ack", json.dumps({"id": event_id}))
            until(lambda: all(_acked(db_path).values()), 10, "every message acknowledged")
    finally:
        code, _, err, _ = h.stop()
    assert code == 0, err


def test_ack_flood_is_counted_not_logged_line_by_line(tmp_path):
    h, ep = publisher_daemon(tmp_path)
    n = 20000
    try:
        with client(ep) as s:
            statuses, _s = _collect(s, "posed/r7/status")
            until(lambda: statuses and statuses[-1]["events"]["unacknowledged"] >= 3, 30, "three fall messages")
            pub = s.declare_publisher("posed/r7/events/ack", congestion_control=zenoh.CongestionControl.BLOCK)
            kinds = [b"\xff\xfe not utf-8 \xc3\x28",                    # not UTF-8
                     ("x" * 100_000).encode(),                         # an id far too long
                     b'{"id": "0123", "state": "nonsense"}',           # no such state
                     b"line one\nline two",                            # control characters
                     b"{not json"]
            for i in range(n):
                pub.put(kinds[i % len(kinds)] if i % 2 else f"unknown-{i}".encode())
            until(lambda: statuses and (lambda a: a["rejected"] + a["unknown"])(statuses[-1]["events"]["acks"]) >= n,
                  120, "every acknowledgement counted")
            a = statuses[-1]["events"]["acks"]
            assert a == {"accepted": 0, "unknown": n // 2, "rejected": n // 2}
            assert statuses[-1]["events"]["unacknowledged"] >= 3               # nothing was acknowledged
    finally:
        code, out, err, _ = h.stop()
    assert code == 0, err
    ack_lines = [x for x in h.log_lines() if "ack" in str(x.get("event", ""))]
    assert 0 < len(ack_lines) <= 60, len(ack_lines)
    longest = max(len(json.dumps(x)) for x in ack_lines)
    assert longest < 1500, longest                     # one bounded line: the 100 kB id is truncated
    assert "Traceback" not in out + err


@pytest.mark.parametrize("payload, expected", [
    (b"e1", ("e1", None)), (b"  e1\n", ("e1", None)), (b'{"id": "e2"}', ("e2", None)),
    (b'{"id": "e2", "state": "alarm"}', ("e2", "alarm")), (b'{"id": 7}', ("7", None)),
])
def test_ack_message_parsed(payload, expected):
    from posed.daemon.bus import acks

    got = acks.parse_ack_message(payload)
    assert (got.id, got.state) == expected


@pytest.mark.parametrize("payload, why", [
    (b"\xff\xfe", "UTF-8"), (b"", "empty"), (b"   ", "empty"), (b"{not json", "JSON"), (b'{"other": 1}', "id"),
    (b'{"id": "e", "state": "nonsense"}', "state"), (b"a\nb", "control"), (b"x" * 300, "long"),
    (b"y" * 5000, "bytes"), (b'{"id": ""}', "empty"), (b'{"id": "e", "state": 3}', "state"),
])
def test_bad_ack_messages_rejected_with_reason(payload, why):
    from posed.daemon.bus import acks

    with pytest.raises(acks.BadAck, match=why):
        acks.parse_ack_message(payload)
