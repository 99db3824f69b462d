"""The live page after months of use: the hub holds the fall events the page shows (the last 7 days) and every
event not acknowledged, however old — never the whole past. A real Hub (and a real server with a headless
Chromium) fed thousands of falls over months: what it holds and what a new page is sent stay bounded, the old
acknowledged events are gone (from an open page too), an open alarm of months ago is still listed with its
button, and events acknowledged elsewhere (the robot's journal says so) show as acknowledged."""

from __future__ import annotations

import datetime as dt
import json

import pytest

from posed.falls import FallEvent
from posed.viz.web.fall_list import KEEP_S, MAX_EVENTS
from posed.viz.web.hub import PRUNE_EVERY_S, Hub
from posed.viz.web.server import WebServer

DAY = 86400.0
T_END = dt.datetime(2026, 12, 7, 12, 0, tzinfo=dt.UTC).timestamp()


class Clocks:
    """The receiving machine's clocks, moved by the test (months pass in a second)."""

    def __init__(self, wall: float) -> None:
        self.wall, self.mono = wall, 1000.0

    def advance_to(self, wall: float) -> None:
        self.mono += max(0.0, wall - self.wall)
        self.wall = max(self.wall, wall)


def _iso(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _fall(eid: str, t0: float, states=("falling", "on_floor", "recovered")) -> list[FallEvent]:
    return [FallEvent(eid, "r", s, 1.0, 1.5, 2.0 + k, 0.9, wall_time=_iso(t0 + 5 * k)) for k, s in enumerate(states)]


def _months(hub: Hub, clocks: Clocks, n: int, days: float, open_at: dict[int, str], page=None,
            seen: list | None = None) -> dict[str, float]:
    """``n`` falls over ``days`` ending at T_END, received live as the time passes; every one acknowledged by
    the page a minute later except those of ``open_at`` (index -> why). Returns each event's start. ``page``:
    a page's queue, read as a page does into ``seen``."""
    starts = {}
    for i in range(n):
        t0 = T_END - days * DAY + (i + 0.5) * days * DAY / n
        eid = f"ev{i:05d}" + "x" * 8
        starts[eid] = t0
        states = ("falling", "on_floor", "alarm") if i in open_at else ("falling", "on_floor", "recovered")
        for ev in _fall(eid, t0, states):
            clocks.advance_to(t0 + 5)
            hub.on_event("r", ev)
        clocks.advance_to(t0 + 60)
        if i not in open_at:
            hub.on_acked(eid, True)
        hub.tick()
        while page is not None and not page.empty():
            seen.append(page.get())
    clocks.advance_to(T_END + PRUNE_EVERY_S + 1)
    hub.tick()
    while page is not None and not page.empty():
        seen.append(page.get())
    return starts


def _hub(clocks: Clocks) -> Hub:
    return Hub("r", clock=lambda: clocks.mono, monotonic=lambda: clocks.mono, wall=lambda: clocks.wall)


def test_months_of_falls_keep_the_hub_bounded_and_every_open_alarm():
    clocks = Clocks(T_END - 121 * DAY)
    hub = _hub(clocks)
    page = hub.subscribe()
    # 3,000 falls over 120 days (25 a day), three never acknowledged: one four months old, two of this week
    open_at = {3: "four months ago", 2990: "this week", 2999: "today"}
    seen: list = []
    starts = _months(hub, clocks, 3000, 120.0, open_at, page, seen)
    snap = hub.snapshot()
    held = {m["id"] for m in snap["events"]}
    open_ids = {f"ev{i:05d}xxxxxxxx" for i in open_at}
    week = {e for e, t0 in starts.items() if t0 + 10 >= clocks.wall - KEEP_S}
    assert open_ids <= held                                       # open alarms are never dropped, however old
    assert held == week | open_ids                                # the page's window, and the open ones
    assert len(held) <= MAX_EVENTS and len(snap["events"]) <= 3 * MAX_EVENTS
    assert "ev00003xxxxxxxx" in held and starts["ev00003xxxxxxxx"] < T_END - 115 * DAY
    assert not set(snap["acked"]) & open_ids and set(snap["acked"]) <= held
    assert len(json.dumps(snap)) < 150_000                        # what a new page is sent first (all: 1.1 MB)
    # the pages were told what was dropped, and every dropped event was an acknowledged one
    forgotten = {i for m in seen if m["type"] == "forget" for i in m["ids"]}
    assert forgotten and not forgotten & open_ids and not forgotten & held
    assert len(forgotten) + len(held) == 3000


def test_a_busy_week_is_capped_by_count_and_open_ones_are_never_cut():
    clocks = Clocks(T_END - 8 * DAY)
    hub = _hub(clocks)
    # 100 falls a day for a week, all acknowledged: more than the page lists; the oldest acknowledged go first
    _months(hub, clocks, 700, 7.0, {})
    held = sorted({m["id"] for m in hub.snapshot()["events"]})
    assert len(held) == MAX_EVENTS and held[-1] == "ev00699xxxxxxxx" and held[0] == f"ev{700 - MAX_EVENTS:05d}xxxxxxxx"
    # nobody acknowledges anything for a while: every open event stays, beyond the count
    clocks2 = Clocks(T_END - 8 * DAY)
    hub2 = _hub(clocks2)
    _months(hub2, clocks2, MAX_EVENTS + 50, 7.0, dict.fromkeys(range(MAX_EVENTS + 50), "open"))
    assert hub2.held_events() == MAX_EVENTS + 50


def test_falls_nobody_acknowledges_are_dropped_once_over_and_old_but_an_alarm_is_kept():
    """A robot whose page nobody opens: no fall is ever acknowledged. Those that ended with the person up before
    an alarm was due are settled and leave with the page's window; an alarm nobody acknowledged stays."""
    clocks = Clocks(T_END - 121 * DAY)
    hub = _hub(clocks)
    open_at = {3: "an alarm four months ago"}
    starts = {}
    for i in range(3000):
        t0 = T_END - 120 * DAY + (i + 0.5) * 120 * DAY / 3000
        eid = f"ev{i:05d}" + "x" * 8
        starts[eid] = t0
        for ev in _fall(eid, t0, ("falling", "on_floor", "alarm") if i in open_at else
                        ("falling", "on_floor", "recovered")):
            clocks.advance_to(t0 + 5)
            hub.on_event("r", ev)
        hub.tick()
    clocks.advance_to(T_END + PRUNE_EVERY_S + 1)
    hub.tick()
    held = {m["id"] for m in hub.snapshot()["events"]}
    week = {e for e, t0 in starts.items() if t0 + 10 >= clocks.wall - KEEP_S}
    assert "ev00003xxxxxxxx" in held                              # the alarm nobody acknowledged
    assert held == week | {"ev00003xxxxxxxx"}                     # before: all 3,000, for ever
    assert hub.held_events() <= MAX_EVENTS + 1


def test_acknowledged_elsewhere_is_learned_from_the_robots_journal():
    """An event acknowledged by another receiver (a phone, `posed ack`): the hub learns it from the stored
    messages, tells the pages, and drops it once it is older than the page's window."""
    clocks = Clocks(T_END - 30 * DAY)
    hub = _hub(clocks)
    for ev in _fall("elsewhere" + "x" * 7, T_END - 29 * DAY):
        hub.on_event("r", ev)
    page = hub.subscribe()
    stored = [{"id": "elsewhere" + "x" * 7, "state": s, "acked_at": T_END - 29 * DAY + 100, "acked_by": "Anna"}
              for s in ("falling", "on_floor")]
    hub.on_history(stored)                                       # the third message is not acknowledged yet
    assert not hub.is_acked("elsewherexxxxxxx")
    hub.on_history([*stored, {**stored[0], "state": "recovered"}])
    assert hub.is_acked("elsewherexxxxxxx")
    assert page.get() == {"type": "acked", "id": "elsewherexxxxxxx", "confirmed": True}
    clocks.advance_to(T_END)
    hub.tick()
    assert hub.snapshot()["events"] == [] and page.get() == {"type": "forget", "ids": ["elsewherexxxxxxx"]}


class _Journal:
    """The robot's side as the page reaches it: its stored messages of the last week (oldest first)."""

    def __init__(self) -> None:
        self.messages: list[dict] = []

    def ack(self, event_id, by=None):
        raise AssertionError("no acknowledgement in this test")

    def history(self, since=None, until=None):
        return self.messages


@pytest.fixture
def served(served_page):
    return lambda hub, link: served_page(hub, link, "window.posedView && posedView.labels && posedView.labels.theta_kn_l")


def test_a_page_open_for_months_drops_old_falls_and_keeps_the_open_alarm(served):
    clocks = Clocks(T_END - 91 * DAY)
    hub = _hub(clocks)
    journal = _Journal()
    old_open = "ev00002xxxxxxxx"
    for ev in _fall(old_open, T_END - 90 * DAY, ("falling", "on_floor", "alarm")):
        clocks.advance_to(T_END - 90 * DAY)
        hub.on_event("r", ev)
    b = served(hub, journal)
    b.wait_for(f"!!document.querySelector('button.ack[data-event-id=\"{old_open}\"]')", 30, "the alarm's button")
    # three months pass with the page open: 2,000 falls, acknowledged on another page (the robot's journal says)
    open_at = {2: "the alarm of three months ago"}
    starts = _months(hub, clocks, 2000, 90.0, {**open_at, **{i: "acked elsewhere" for i in range(1990, 2000)}})
    elsewhere = [f"ev{i:05d}xxxxxxxx" for i in range(1990, 2000)]
    journal.messages = [{"id": e, "state": s, "wall_time": _iso(starts[e] + 5 * k), "confidence": 0.9,
                         "published_at": starts[e] + 5 * k, "acked_at": starts[e] + 90, "acked_by": "Anna",
                         "restored": None, "without_frames_s": None}
                        for e in elsewhere for k, s in enumerate(("falling", "on_floor", "alarm"))]
    week = {e for e, t0 in starts.items() if t0 + 10 >= clocks.wall - KEEP_S} - {old_open}
    b.js("loadHistory()")
    b.wait_for(f"posedView.acked[{json.dumps(elsewhere[-1])}] === true", 30, "the acknowledgement from elsewhere")
    ids = b.js("[...new Set(Object.values(posedView.events).map(e => e.id))]")
    assert set(ids) == week | {old_open}, len(ids)               # the page forgot what the server forgot
    assert b.js("document.getElementById('alarm').textContent") == "1 fall event(s) not acknowledged"
    b.js("document.querySelector('#events li.more button').click()")  # show all: the old alarm is listed
    assert b.js(f"!!document.querySelector('button.ack[data-event-id=\"{old_open}\"]')")
    assert b.js(f"document.querySelector('li[data-event-id=\"{elsewhere[-1]}\"]').textContent").count(
        "acknowledged ✓ by Anna") == 1
    # a page opened now is sent the week and the open alarm, not three months
    b2 = served(hub, journal)
    assert set(b2.js("[...new Set(Object.values(posedView.events).map(e => e.id))]")) == week | {old_open}
    assert b2.js(f"!!document.querySelector('#events li[data-event-id=\"{old_open}\"]')") is False   # not in the 6
    assert "1 not acknowledged" in b2.js("document.querySelector('#events li.more').textContent")


class _JournalLink:
    """The robot's journal as the server reads it (a real EventJournal on SQLite): the page's window, or a span."""

    def __init__(self, path, now: float) -> None:
        from posed.daemon.outbox.journal import EventJournal

        self.journal = EventJournal(path, readonly=True)
        self.now = now
        self.reads: list = []

    def ack(self, event_id, by=None):
        raise AssertionError("no acknowledgement in this test")

    def history(self, since=None, until=None):
        self.reads.append((since, until))
        since = self.now - KEEP_S if since is None else since
        return [{"id": s.event.id, "state": s.event.state, "wall_time": s.event.wall_time, "acked_at": s.acked_at,
                 "acked_by": s.acked_by} for s in self.journal.query(since, until, limit=10000)]


def test_old_events_acknowledged_while_this_side_did_not_know_are_learned_and_dropped(tmp_path):
    """A robot back on the bus publishes months of alarms this side never saw, most of them acknowledged
    long ago (by `posed ack` on the robot): the server reads the robot's journal a day at a time from the oldest
    one it holds open, drops what it learns was acknowledged, and keeps the one alarm nobody acknowledged."""
    from posed.daemon.outbox.journal import EventJournal

    clock = {"now": 0.0}
    path = tmp_path / "events.sqlite3"
    clocks = Clocks(T_END)
    hub = _hub(clocks)
    with EventJournal(path, clock=lambda: clock["now"]) as journal:
        for i in range(1500):                           # 25 falls a day for 60 days
            t0 = T_END - 60 * DAY + (i + 0.5) * 60 * DAY / 1500
            eid = f"ev{i:05d}" + "x" * 8
            for ev in _fall(eid, t0, ("falling", "on_floor", "alarm")):     # alarms: never settled unacknowledged
                clock["now"] = unix = dt.datetime.fromisoformat(ev.wall_time.replace("Z", "+00:00")).timestamp()
                journal.append(ev)
                hub.on_event("r", ev)                   # arrives here only now, all at once
                assert unix <= T_END
            if i != 7:
                clock["now"] = t0 + 60
                journal.acknowledge(eid, by="Anna")
    assert hub.held_events() == 1500
    link = _JournalLink(path, T_END)
    server = WebServer(hub, link, "127.0.0.1", 0)
    try:
        server.sync_acks()
        hub.tick()
        held = {m["id"] for m in hub.snapshot()["events"]}
        assert "ev00007xxxxxxxx" in held and not hub.is_acked("ev00007xxxxxxxx")
        assert len(held) <= MAX_EVENTS and all(hub.is_acked(e) for e in held - {"ev00007xxxxxxxx"})
        assert len(link.reads) <= 62                    # a read a day from the oldest open one, then the week
    finally:
        server.server_close()
        link.journal.close()
