"""What a query on posed/ROBOT/privacy/pause asks (``daemon.bus.pause_query``): every accepted form of ``for``
and ``by``, and every rejection named with what to give instead; the reply to a query through a stand-in query
object (the real queryable runs in tests/daemon/test_privacy_e2e.py)."""

from __future__ import annotations

import json

import pytest

from posed.daemon.bus.pause_query import (
    MAX_BY_CHARS,
    BadPause,
    PauseRefused,
    PauseRequest,
    answer_pause,
    parse_by,
    parse_duration,
    parse_pause,
)
from posed.daemon.logs import get
from posed.daemon.proc.throttle import Throttle


@pytest.mark.parametrize("text,seconds", [
    ("900", 900.0), ("90.5", 90.5), ("30s", 30.0), ("15m", 900.0), ("1h", 3600.0), ("1h30m", 5400.0),
    ("1h30m15s", 5415.0), ("2m30s", 150.0), (" 15M ", 900.0), ("0", 0.0), ("0s", 0.0), ("resume", 0.0),
    ("RESUME", 0.0), ("1.5h", 5400.0),
])
def test_durations(text, seconds):
    assert parse_duration(text) == seconds


@pytest.mark.parametrize("text,says", [
    ("", "for is empty"), ("   ", "for is empty"),
    ("soon", "is not a duration"), ("15 min", "is not a duration"), ("h", "is not a duration"),
    ("1h-30m", "is not a duration"), ("30m1h", "is not a duration"), ("15x", "is not a duration"),
    ("-5", "is negative"), ("-1h", "is not a duration"),
    ("inf", "not a finite duration"), ("nan", "not a finite duration"),
])
def test_bad_durations_are_named_with_the_accepted_forms(text, says):
    with pytest.raises(BadPause) as exc:
        parse_duration(text)
    assert says in str(exc.value)
    if says != "is negative":
        assert "15m" in str(exc.value)          # the usage: how to give it
    else:
        assert "0 to resume" in str(exc.value)


def test_by():
    assert parse_by(None) is None
    assert parse_by("") is None and parse_by("   ") is None
    assert parse_by(" voice ") == "voice"
    assert parse_by("x" * MAX_BY_CHARS) == "x" * MAX_BY_CHARS
    with pytest.raises(BadPause, match=f"at most {MAX_BY_CHARS}"):
        parse_by("x" * (MAX_BY_CHARS + 1))
    with pytest.raises(BadPause, match="control characters"):
        parse_by("voice\x1b[31m")
    with pytest.raises(BadPause, match="control characters"):
        parse_by("a\nb")


def test_parameters():
    assert parse_pause({"for": "15m", "by": "voice"}) == PauseRequest(900.0, "voice")
    assert parse_pause({"for": "15m"}) == PauseRequest(900.0, None)
    assert parse_pause({"for": "0", "by": "app"}).resume
    assert parse_pause({"for": "15m&by=voice"}) == PauseRequest(900.0, "voice")     # the URL habit
    with pytest.raises(BadPause, match="for is missing"):
        parse_pause({"by": "voice"})
    with pytest.raises(BadPause, match="for is missing"):
        parse_pause(None)
    with pytest.raises(BadPause, match="at most"):
        parse_pause({"for": "15m", "by": "y" * 65})


class _Query:
    """A stand-in for a zenoh.Query: the parameters it carries and what was answered."""

    def __init__(self, params: dict) -> None:
        self.parameters = params
        self.ok: list = []
        self.err: list = []

    def reply(self, key, payload, encoding=None) -> None:
        self.ok.append((key, json.loads(payload)))

    def reply_err(self, payload, encoding=None) -> None:
        self.err.append(json.loads(payload))


def test_the_reply_and_the_error_replies():
    asked = []

    def ask(request):
        asked.append(request)
        if request.for_s > 7200:
            raise PauseRefused("fall event abc is open and not acknowledged", "acknowledge fall abc first")
        return {"format": "posed.privacy", "paused": True}

    log, throttle = get("test"), Throttle()
    q = _Query({"for": "15m", "by": "voice"})
    answer_pause(q, "posed/r1/privacy/pause", ask, log, throttle)
    assert q.ok == [("posed/r1/privacy/pause", {"format": "posed.privacy", "paused": True})] and not q.err
    assert asked == [PauseRequest(900.0, "voice")]

    q = _Query({"for": "later"})
    answer_pause(q, "posed/r1/privacy/pause", ask, log, throttle)
    assert not q.ok and q.err[0]["format"] == "posed.error" and "for='later' is not a duration" in q.err[0]["error"]
    assert "15m" in q.err[0]["fix"] and len(asked) == 1                # never asked the keeper

    q = _Query({"for": "3h"})
    answer_pause(q, "posed/r1/privacy/pause", ask, log, throttle)
    err = q.err[0]
    assert "fall event abc is open" in err["error"] and "acknowledge fall abc first" in err["error"]
    assert err["fix"] == "acknowledge fall abc first"
