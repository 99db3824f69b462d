"""Property-based fuzzing of acknowledgements (anything any process puts on ``posed/ROBOT/events/ack``),
through the bus link's own ack handler with real Zenoh payload objects: it never raises (an exception would
end up on a Zenoh thread), hands the stage only a bounded printable id and a known state, and logs at most a
bounded, rate-limited line for what it rejects."""

from __future__ import annotations

import contextlib
import json
from types import SimpleNamespace

import zenoh
from hypothesis import given
from hypothesis import strategies as st

from posed.daemon.bus.link import BusLink
from posed.daemon.config.sections import ZenohConfig
from posed.falls import FALL_STATES
from tests.fuzz.strategies import FUZZ, deep_nesting, json_values

EVENT_ID = "0123456789abcdef0123456789abcdef"


class RecordingLog:
    """A stand-in for the structlog logger: keeps every call."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, str, dict]] = []

    def __getattr__(self, level):
        return lambda event, **kw: self.calls.append((level, event, kw))


def _ack_json(**fields) -> bytes:
    return json.dumps(fields, allow_nan=True).encode()


payloads = st.one_of(
    st.binary(max_size=300),
    st.text(max_size=200).map(lambda s: s.encode("utf-8", "surrogatepass")),
    st.just(EVENT_ID.encode()),
    st.builds(lambda v: _ack_json(id=v), json_values),
    st.builds(lambda s: _ack_json(id=EVENT_ID, state=s), st.one_of(st.sampled_from(FALL_STATES), json_values)),
    json_values.map(lambda v: json.dumps(v, allow_nan=True).encode()),
    st.integers(100, 3000).map(lambda n: ('{"id": ' + deep_nesting(n) + "}").encode()),
    st.integers(1, 200_000).map(lambda n: b"a" * n),
)


def _link(acks: list, log: RecordingLog) -> BusLink:
    return BusLink(ZenohConfig(), "fuzz", contextlib.ExitStack(), log, history=lambda *a: [],
                   on_ack=lambda *a: acks.append(a))


@FUZZ
@given(batch=st.lists(payloads, min_size=1, max_size=20))
def test_any_ack_payload_is_taken_or_rejected_quietly(batch):
    acks: list = []
    log = RecordingLog()
    link = _link(acks, log)
    for raw in batch:
        link._on_ack_sample(SimpleNamespace(payload=zenoh.ZBytes(raw), key_expr="posed/fuzz/events/ack"))
    assert len(acks) <= len(batch)
    for args in acks:
        event_id, state = args[0], (args[1] if len(args) > 1 else None)
        assert isinstance(event_id, str) and 0 < len(event_id) <= 128 and event_id.isprintable()
        assert not any(c.isspace() for c in event_id)
        assert state is None or state in FALL_STATES
    warnings = [c for c in log.calls if c[0] in ("warning", "error")]
    assert len(warnings) <= len(batch) - len(acks)
    for call in warnings:
        assert len(repr(call)) < 2000, "a rejected ack must be logged as one bounded line"


@FUZZ
@given(state=st.sampled_from(FALL_STATES), pad=st.text(" \t\n", max_size=3))
def test_valid_acks_are_taken(state, pad):
    acks: list = []
    link = _link(acks, RecordingLog())
    for raw in (EVENT_ID, json.dumps({"id": EVENT_ID}), json.dumps({"id": EVENT_ID, "state": state})):
        link._on_ack_sample(SimpleNamespace(payload=zenoh.ZBytes((pad + raw + pad).encode())))
    assert [a[0] for a in acks] == [EVENT_ID] * 3
    assert [a[1] if len(a) > 1 else None for a in acks] == [None, None, state]
