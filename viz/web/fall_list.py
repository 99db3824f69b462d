"""The fall events the live page lists, bounded: what a page that opens is sent first and what the web stage
holds in memory over months of use.

Kept: every event that is not settled, however old (an alarm nobody acknowledged, a fall not yet over, is never
dropped from the page); and the settled events of the page's window (``KEEP_S``, the event history's "last 7
days"), at most ``MAX_EVENTS`` events in all (the newest settled ones first; a safety net for a robot that
reports many falls a day). Settled: acknowledged, or over without an alarm (the person got up before it was
due) — on a robot whose page nobody opens, nothing is acknowledged, and those falls would otherwise be held
for ever. An event's time is its newest message's ``wall_time`` (the robot's clock, as the history's
window), else when it was received here.

An event is acknowledged when every message of it held here is: through this page (``ack``), or as the
robot's journal says (``learn``: the history the page and the hub read). A new message (a later state) opens
it again, as the daemon republishes it until that message is acknowledged too.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

KEEP_S = 7 * 86400.0        # the page's window: its event history shows the last 7 days (bus.HISTORY_SINCE)
MAX_EVENTS = 200            # events held at most (acknowledged ones beyond it go first; open ones never)


def unix_of(wall_time) -> float | None:
    """A message's ``wall_time`` (ISO 8601, UTC unless it says otherwise) as unix seconds; None when absent or
    unreadable."""
    if not isinstance(wall_time, str) or not wall_time:
        return None
    try:
        t = dt.datetime.fromisoformat(wall_time.replace("Z", "+00:00"))
    except ValueError:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.UTC)
    return t.timestamp()


@dataclass(frozen=True)
class Forgotten:
    """What one ``prune`` dropped: event ids, and why (beyond the window, or beyond the count)."""

    ids: tuple[str, ...]
    old: int
    over_count: int


class FallList:
    """Not thread-safe: the hub calls it with its lock held."""

    def __init__(self, keep_s: float = KEEP_S, max_events: int = MAX_EVENTS) -> None:
        self.keep_s, self.max_events = keep_s, max_events
        self._msgs: dict[str, dict[str, dict]] = {}     # id -> state -> message, in order of arrival
        self._at: dict[str, float] = {}                 # id -> unix time of its newest message
        self._robot: dict[str, str] = {}                # id -> the robot it is from
        self._acked: set[str] = set()

    def __len__(self) -> int:
        return len(self._msgs)

    def add(self, msg: dict, received_unix: float) -> bool:
        """A message (``id``, ``state``, ``wall_time``, ``robot``); False when it is a repeat (the daemon
        republishes until acknowledged). A new state needs its own acknowledgement."""
        eid, state = msg["id"], msg["state"]
        states = self._msgs.setdefault(eid, {})
        if state in states:
            return False
        states[state] = msg
        at = unix_of(msg.get("wall_time"))
        self._at[eid] = max(self._at.get(eid, -1e300), at if at is not None else received_unix)
        if msg.get("robot"):
            self._robot[eid] = msg["robot"]
        self._acked.discard(eid)
        return True

    def ack(self, event_id: str) -> bool:
        """Every message of the event so far is acknowledged; False for an event not held here."""
        if event_id not in self._msgs:
            return False
        self._acked.add(event_id)
        return True

    def learn(self, stored: list[dict]) -> list[str]:
        """The robot's journal (stored messages with ``id``, ``state``, ``acked_at``): the events held here whose
        every message it shows acknowledged become acknowledged; returns their ids."""
        acked: dict[str, set[str]] = {}
        for m in stored:
            if isinstance(m, dict) and m.get("acked_at") is not None and m.get("id") in self._msgs:
                acked.setdefault(m["id"], set()).add(m.get("state"))
        out = []
        for eid, states in acked.items():
            if eid not in self._acked and set(self._msgs[eid]) <= states:
                self._acked.add(eid)
                out.append(eid)
        return out

    def robot_of(self, event_id: str) -> str | None:
        return self._robot.get(event_id)

    def is_acked(self, event_id: str) -> bool:
        return event_id in self._acked

    def open_since(self, after: float | None = None) -> float | None:
        """The time of the oldest event not known to be acknowledged (of those after ``after``; None: none)."""
        times = [self._at[e] for e in self._msgs if e not in self._acked and (after is None or self._at[e] > after)]
        return min(times) if times else None

    def messages(self) -> list[dict]:
        return [m for states in self._msgs.values() for m in states.values()]

    def acked(self) -> list[str]:
        return sorted(self._acked)

    def settled(self, event_id: str) -> bool:
        """Acknowledged, or over without an alarm (``recovered`` and never ``alarm``)."""
        states = self._msgs.get(event_id, {})
        return event_id in self._acked or ("recovered" in states and "alarm" not in states)

    def prune(self, now_unix: float) -> Forgotten:
        """Drop the settled events older than the window, then the oldest settled ones while more than
        ``max_events`` are held. Events not settled are never dropped."""
        cutoff = now_unix - self.keep_s
        settled = [e for e in self._msgs if self.settled(e)]
        old = [e for e in settled if self._at[e] < cutoff]
        for e in old:
            self._forget(e)
        over = []
        if len(self._msgs) > self.max_events:
            kept = sorted((e for e in settled if e in self._msgs), key=lambda e: self._at[e])
            over = kept[:len(self._msgs) - self.max_events]
            for e in over:
                self._forget(e)
        return Forgotten(tuple(old + over), len(old), len(over))

    def _forget(self, event_id: str) -> None:
        self._msgs.pop(event_id, None)
        self._at.pop(event_id, None)
        self._robot.pop(event_id, None)
        self._acked.discard(event_id)
