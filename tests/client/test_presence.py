"""``client.Status.presence``: the status's ``presence`` (the absence notice, docs/falls.md) typed as
``client.Presence``, None when the status has none, null, or a malformed one (as ``Status.watch``); and its words,
written once for ``posed watch`` and the web page: ``client.presence_note`` and ``client.presence_change``."""

from __future__ import annotations

import datetime as dt
from zoneinfo import ZoneInfo

import pytest

from posed.client import Presence, Status, presence_change, presence_note

NOW = dt.datetime(2026, 12, 7, 17, 12, tzinfo=ZoneInfo("Europe/Berlin")).timestamp()
H, MIN = 3600.0, 60.0
ABSENT = {"last_seen_unix": NOW - 3 * H - 10 * MIN, "absent_s": 3 * H + 10 * MIN, "usual_s": 2 * H + 5 * MIN,
          "notice_after_s": 3 * H + 5 * MIN, "days": 14, "learn_days": 7, "learning": False, "absent": True,
          "absent_since_unix": NOW - 5 * MIN}
SEEN = dict(ABSENT, last_seen_unix=NOW - 12 * MIN, absent_s=12 * MIN, absent=False, absent_since_unix=None)
LEARNING = dict(SEEN, usual_s=None, notice_after_s=None, days=3, learning=True)


def status(presence=..., **more) -> Status:
    obj = {"state": "running", "robot": "home", "time_unix": NOW, **more}
    if presence is not ...:
        obj["presence"] = presence
    return Status.from_json(obj)


def test_a_good_presence_is_typed():
    p = status(ABSENT).presence
    assert p == Presence(NOW - 3 * H - 10 * MIN, 3 * H + 10 * MIN, 2 * H + 5 * MIN, 3 * H + 5 * MIN, 14, 7, False, True,
                         NOW - 5 * MIN)
    assert isinstance(p.absent_s, float) and isinstance(p.days, int)
    learning = status(LEARNING).presence
    assert learning.learning and learning.usual_s is None and learning.notice_after_s is None and not learning.absent
    never = status(dict(LEARNING, last_seen_unix=None, absent_s=0)).presence
    assert never is not None and never.last_seen_unix is None
    with pytest.raises(AttributeError):
        p.absent = False        # frozen


@pytest.mark.parametrize("presence", [..., None])
def test_no_presence_or_null_is_none(presence):
    assert status(presence).presence is None


@pytest.mark.parametrize("bad", [
    "absent", 3, [ABSENT],                                   # not an object
    {},                                                      # nothing in it
    dict(ABSENT, absent="yes"), dict(ABSENT, absent=None), dict(ABSENT, learning=1),
    dict(ABSENT, absent_s="long"), dict(ABSENT, absent_s=None), dict(ABSENT, absent_s=True),
    dict(ABSENT, absent_s=-5.0), dict(ABSENT, absent_s=float("nan")), dict(ABSENT, absent_s=float("inf")),
    dict(ABSENT, days=2.5), dict(ABSENT, days=-1), dict(ABSENT, days=True), dict(ABSENT, learn_days="7"),
    {k: v for k, v in ABSENT.items() if k != "learning"},
])
def test_a_malformed_presence_is_none(bad):
    assert status(bad).presence is None
    assert status(bad).state == "running"                    # the rest of the status is read as ever


def test_a_bad_optional_field_is_none_not_the_whole():
    p = status(dict(ABSENT, usual_s="two hours", last_seen_unix=False, absent_since_unix=[1])).presence
    assert p is not None and p.absent and p.usual_s is None and p.last_seen_unix is None
    assert p.absent_since_unix is None
    odd = status(dict(SEEN, last_seen_unix=float("nan"), usual_s=float("inf"))).presence
    assert odd.last_seen_unix is None and odd.usual_s is None
    assert presence_note(odd, NOW, "Europe/Berlin") == "not seen yet"
    far = status(dict(SEEN, last_seen_unix=-1e300)).presence       # no calendar holds it: said, never raised
    assert presence_note(far, NOW, "Europe/Berlin").startswith("last seen ? (")


def test_the_words_of_the_page():
    berlin = "Europe/Berlin"
    assert presence_note(status(ABSENT).presence, NOW, berlin) == \
        "not seen for 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)"
    assert presence_note(status(SEEN).presence, NOW, berlin) == "last seen 17:00 (12 min ago)"
    assert presence_note(status(SEEN).presence, NOW, "Asia/Tokyo") == "last seen 01:00 (12 min ago)"  # its zone
    assert presence_note(status(SEEN).presence, NOW + 24 * H, berlin) == \
        "last seen 2026-12-07 17:00 (24 h 12 min ago)"                                     # dated when not today
    assert presence_note(status(SEEN).presence, NOW + 9 * H, "Asia/Tokyo") == "last seen 01:00 (9 h 12 min ago)"
    assert presence_note(status(dict(SEEN, last_seen_unix=NOW - 0.1, in_view=True)).presence, NOW, berlin) == "in view"
    assert presence_note(status(dict(SEEN, last_seen_unix=NOW - 40)).presence, NOW, berlin) == "last seen 17:11 (< 1 min ago)"
    assert presence_note(status(LEARNING).presence, NOW, berlin) == \
        "last seen 17:00 (12 min ago); learning the routine: 3 of 7 days"
    assert presence_note(status(dict(LEARNING, last_seen_unix=None)).presence, NOW, berlin) == \
        "not seen yet; learning the routine: 3 of 7 days"
    one = status(dict(ABSENT, days=1, usual_s=2 * H, absent_s=4 * H + 30)).presence
    assert presence_note(one, NOW, berlin) == \
        "not seen for 4 h — longer than on the last day (usually back within 2 h)"
    assert presence_note(None, NOW, berlin) == ""
    assert presence_note(status(SEEN).presence, NOW, "No/Such_Zone").startswith("last seen ")   # this machine's


def test_the_words_of_posed_watch_once_per_change():
    seen, absent = status(SEEN).presence, status(ABSENT).presence
    begun = "PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)"
    assert presence_change(seen, absent) == begun
    assert presence_change(None, absent) == begun                     # the first status heard: absent already
    later = status(dict(ABSENT, absent_s=3 * H + 20 * MIN)).presence
    assert presence_change(absent, later) is None                     # not on every status
    back = status(dict(SEEN, last_seen_unix=ABSENT["last_seen_unix"] + 3 * H + 25 * MIN, absent_s=0)).presence
    assert presence_change(later, back) == "person seen again after 3 h 25 min"
    assert presence_change(back, status(SEEN).presence) is None
    assert presence_change(seen, seen) is None and presence_change(None, seen) is None
    assert presence_change(absent, None) is None                      # the presence gone: nothing said
    assert presence_change(absent, status(dict(ABSENT, absent=False)).presence) is None   # ended, not seen
