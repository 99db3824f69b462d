"""Property-based fuzzing of the ``posed/ROBOT/events/history`` query parameters (anything any process puts
after ``?``), parsed by Zenoh's own ``Parameters`` and answered by the bus's handler over a real SQLite
journal: it never raises, and either answers an error naming the bad parameter or looks up finite times and a
limit within 0..HISTORY_MAX_LIMIT."""

from __future__ import annotations

import json
import math
import time

import zenoh
from hypothesis import given
from hypothesis import strategies as st

from posed.daemon.bus import queries
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.timeparse import parse_time
from tests.fuzz.strategies import FUZZ

BASE = "posed/fuzz/events/history"
time_texts = st.one_of(
    st.text(max_size=30),
    st.sampled_from(["now", "today", "yesterday", "2h", "-15m", "7d", "1w", "0001-01-01", "9999-12-31T23:59Z",
                     "2024-05-01T14:30+05:00", "1700000000", "1700000000.5", "nan", "inf", "-1", "1e9"]),
    st.integers(min_value=0, max_value=10**12).map(str),
    st.integers(min_value=1, max_value=2000).map(lambda n: "9" * n),
    st.builds(lambda n, u: f"{n}{u}", st.integers(0, 10**400), st.sampled_from(["s", "m", "h", "d", "w"])),
)
limit_texts = st.one_of(st.text(max_size=10), st.integers(-10**6, 10**6).map(str),
                        st.integers(1, 6000).map(lambda n: "1" * n), st.sampled_from(["", "0", "10000", "10001", "٣"]))
params = st.builds(lambda d: ";".join(f"{k}={v}" for k, v in d.items()),
                   st.dictionaries(st.sampled_from(["since", "until", "limit", "n", "x"]),
                                   st.one_of(time_texts, limit_texts), max_size=4))
raw_params = st.one_of(params, st.text(max_size=60))


class Query:
    """A stand-in query holding real Zenoh parameters; keeps the replies."""

    def __init__(self, key: str, parameters: str) -> None:
        self.key_expr = key
        self.parameters = zenoh.Parameters(parameters)
        self.replies: list[tuple[str, str]] = []
        self.errors: list[str] = []

    def reply(self, key, payload, **kw) -> None:
        self.replies.append((key, payload))

    def reply_err(self, payload, **kw) -> None:
        self.errors.append(payload)


class Log:
    def __init__(self) -> None:
        self.warnings: list = []

    def warning(self, event, **kw) -> None:
        self.warnings.append((event, kw))


@FUZZ
@given(raw=raw_params, bare=st.booleans())
def test_any_history_parameters_are_answered(tmp_path_factory, raw, bare):
    journal = EventJournal(tmp_path_factory.mktemp("hist") / "events.sqlite3")
    looked_up: list = []

    def lookup(since, until, limit, event_id=None):
        looked_up.append((since, until, limit))
        return journal.query(since, until, limit, event_id=event_id)

    q = Query(BASE if bare else f"{BASE}/**", raw)
    log = Log()
    try:
        queries.answer_history(q, BASE, lookup, log)
    finally:
        journal.close()
    assert log.warnings == [], f"the lookup failed: {log.warnings}"
    if q.errors:
        assert looked_up == [] and q.replies == [] and len(q.errors) == 1
        err = json.loads(q.errors[0])
        assert any(k in err["error"] for k in ("since", "until", "limit", "time")), err
        return
    (since, until, limit), = looked_up
    assert 0 <= limit <= queries.HISTORY_MAX_LIMIT
    assert all(t is None or math.isfinite(t) for t in (since, until)), (raw, since, until)
    assert len(q.replies) == (1 if bare else 0)


@FUZZ
@given(text=time_texts)
def test_parse_time_gives_finite_seconds_or_names_the_forms(text):
    try:
        t = parse_time(text, now=time.time())
    except ValueError as exc:
        assert str(exc)
        return
    assert math.isfinite(t)
