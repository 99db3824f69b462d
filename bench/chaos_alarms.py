"""The alarm invariant of the chaos campaign: every fall that was opened (``falling`` or ``on_floor``) gets
exactly one ``alarm`` with its id, unless ``recovered`` came first, also when stages are killed mid-fall.

The campaign (:mod:`bench.chaos`) kills a stage -9 at a seeded time after a fall event was received and before
its alarm is due (:class:`MidFallKills`), then judges every event from the journal and the daemon's log
(:func:`judge`):

* ``missing``: opened, no ``alarm`` and no ``recovered`` although the alarm was due ``grace_s`` before the
  daemon stopped (due = the opening message's ``t_impact_unix`` + ``alarm_after_s``, as the daemon's own rule;
  without it, its journal time - ``t_detect`` + ``t_impact``, which leaves out the pipeline's latency);
* ``duplicates``: an ``alarm`` raised more than once for one id (``fall_event`` log lines with that id and
  state ``alarm``; the journal keeps one row per id and state, so a second raising only rewrites the row), or
  received by the observer with two different ``t_detect``;
* ``late``: an ``alarm`` raised more than ``grace_s`` after it was due (raised: its ``fall_event`` log line, or
  its journal time when the log has none; the journal time alone would count a message held in memory while
  the state directory was full);
* ``after_recovered``: an ``alarm`` journalled after the event's ``recovered``;
* ``orphans``: an ``alarm`` or ``recovered`` whose id was never opened;
* ``pending_at_stop``: opened and undecided, its alarm not yet due at the stop (not a failure).

``midfall``: the kills -9 (of the campaign's random faults and of :class:`MidFallKills`) that landed while an
event was open (after its opening message was journalled, before its ``alarm``/``recovered``), per stage, and
how many such events got their alarm or recovered: the coverage, so that a run that never killed a stage
mid-fall does not pass for a test of it. Times: unix seconds.
"""

from __future__ import annotations

import json
import random
import sqlite3
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

OPENING = ("falling", "on_floor")
CLOSING = ("alarm", "recovered")


@dataclass
class Message:
    event_id: str
    state: str
    wall: float                 # unix seconds when journalled
    t_detect: float             # capture clock
    t_impact: float | None      # capture clock
    t_impact_unix: float | None = None     # as stamped on the message


def read_messages(path: Path) -> list[Message]:
    """Every message of the journal (events.sqlite3), read-only; [] when there is none."""
    if not path.is_file():
        return []
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=5)
    try:
        rows = db.execute("SELECT event_id, state, wall, t_detect, body FROM messages").fetchall()
    except sqlite3.Error:
        return []
    finally:
        db.close()
    out = []
    for event_id, state, wall, t_detect, body in rows:
        try:
            obj = json.loads(body)
            t_impact, t_impact_unix = obj.get("t_impact"), obj.get("t_impact_unix")
        except (ValueError, AttributeError):
            t_impact = t_impact_unix = None
        out.append(Message(str(event_id), str(state), float(wall), float(t_detect),
                           float(t_impact) if isinstance(t_impact, (int, float)) else None,
                           float(t_impact_unix) if isinstance(t_impact_unix, (int, float)) else None))
    return out


def alarm_due(opening: Message, alarm_after_s: float) -> float:
    """Unix time when the alarm of the event opened by ``opening`` is due: ``t_impact_unix`` + ``alarm_after_s``;
    for a message without it, the capture clock mapped to unix time through the message's own journal time."""
    if opening.t_impact_unix is not None:
        return opening.t_impact_unix + alarm_after_s
    t_impact = opening.t_impact if opening.t_impact is not None else opening.t_detect
    return opening.wall + (t_impact + alarm_after_s - opening.t_detect)


def judge(messages: list[Message], logs: list[dict], kills: list[tuple[float, str]], alarm_after_s: float,
          t_stop: float, grace_s: float, alarm_bodies: dict[str, set] | None = None) -> dict:
    """The report of the invariant (module docstring). ``logs``: the daemon's JSON log lines; ``kills``:
    (unix time, stage) of every kill -9; ``t_stop``: unix time of the SIGTERM; ``alarm_bodies``: per id, the
    distinct ``t_detect`` of the ``alarm`` messages the observer received."""
    by_id: dict[str, dict[str, Message]] = {}
    for m in messages:
        by_id.setdefault(m.event_id, {})[m.state] = m
    logged: dict[tuple[str, str], int] = {}         # (id, state) -> fall_event log lines
    logged_at: dict[tuple[str, str], float] = {}    # (id, state) -> its first fall_event log line, unix
    for row in logs:
        if row.get("event") == "fall_event":
            key = (str(row.get("id")), str(row.get("state")))
            logged[key] = logged.get(key, 0) + 1
            t = _unix(row.get("timestamp"))
            if t is not None and (key not in logged_at or t < logged_at[key]):
                logged_at[key] = t
    rep: dict = {"opened": 0, "alarms": 0, "recovered_first": 0, "missing": [], "duplicates": [],
                 "late": [], "after_recovered": [], "orphans": [], "pending_at_stop": 0, "alarm_delay_s": None}
    delays = []
    midfall: dict = {"kills": len(kills), "kills_mid_fall": 0, "by_stage": {}, "events_killed_mid_fall": 0,
                     "events_killed_mid_fall_decided": 0, "events_killed_mid_fall_alarm": 0}
    for event_id, states in sorted(by_id.items()):
        opening = min((states[s] for s in OPENING if s in states), key=lambda m: m.wall, default=None)
        alarm, recovered = states.get("alarm"), states.get("recovered")
        if opening is None:
            rep["orphans"].append(event_id)
            continue
        rep["opened"] += 1
        due = alarm_due(opening, alarm_after_s)
        if logged.get((event_id, "alarm"), 0) > 1 or len((alarm_bodies or {}).get(event_id, ())) > 1:
            rep["duplicates"].append(event_id)
        # a message logged but not journalled (the state directory full) still counts as raised
        has_alarm = alarm is not None or logged.get((event_id, "alarm"), 0) > 0
        has_recovered = recovered is not None or logged.get((event_id, "recovered"), 0) > 0
        if has_alarm:
            rep["alarms"] += 1
            raised = logged_at.get((event_id, "alarm"), alarm.wall if alarm is not None else None)
            if raised is not None:
                delays.append(raised - due)
                if raised > due + grace_s:
                    rep["late"].append(event_id)
            if alarm is not None and recovered is not None and recovered.wall < alarm.wall:
                rep["after_recovered"].append(event_id)
        elif has_recovered:
            rep["recovered_first"] += 1
        elif due + grace_s <= t_stop:
            rep["missing"].append(event_id)
        else:
            rep["pending_at_stop"] += 1
        closed = min((m.wall for m in (alarm, recovered) if m is not None), default=t_stop)
        hits = [(t, s) for t, s in kills if opening.wall < t < closed]
        if hits:
            midfall["events_killed_mid_fall"] += 1
            if has_alarm or has_recovered:
                midfall["events_killed_mid_fall_decided"] += 1
            if has_alarm:
                midfall["events_killed_mid_fall_alarm"] += 1
    for t, stage in kills:
        for states in by_id.values():
            opening = min((states[s] for s in OPENING if s in states), key=lambda m: m.wall, default=None)
            if opening is None:
                continue
            closed = min((states[s].wall for s in CLOSING if s in states), default=t_stop)
            if opening.wall < t < closed:
                midfall["kills_mid_fall"] += 1
                midfall["by_stage"][stage] = midfall["by_stage"].get(stage, 0) + 1
                break
    if delays:
        delays.sort()
        rep["alarm_delay_s"] = {"min": round(delays[0], 2), "median": round(delays[len(delays) // 2], 2),
                                "max": round(delays[-1], 2)}
    rep["midfall"] = midfall
    rep["violations"] = len(rep["missing"]) + len(rep["duplicates"]) + len(rep["late"]) + len(rep["after_recovered"])
    return rep


def _unix(timestamp) -> float | None:
    """A log line's ISO timestamp (``2026-12-07T04:26:34.497Z``) as unix seconds; None when it is not one."""
    try:
        return datetime.fromisoformat(str(timestamp).replace("Z", "+00:00")).timestamp()
    except ValueError:
        return None


def undecided_due(messages: list[Message], alarm_after_s: float, opened_before: float) -> float | None:
    """The latest due time (unix) of the events opened before ``opened_before`` that have neither ``alarm`` nor
    ``recovered`` yet; None when there is none (the settle waits until then, plus the grace)."""
    by_id: dict[str, dict[str, Message]] = {}
    for m in messages:
        by_id.setdefault(m.event_id, {})[m.state] = m
    latest = None
    for states in by_id.values():
        if any(s in states for s in CLOSING):
            continue
        opening = min((states[s] for s in OPENING if s in states), key=lambda m: m.wall, default=None)
        if opening is None or opening.wall >= opened_before:
            continue
        due = alarm_due(opening, alarm_after_s)
        latest = due if latest is None else max(latest, due)
    return latest


@dataclass
class MidFallKills:
    """Kill -9 a stage while a fall is open: for a share of the fall events the observer receives (their first
    ``falling`` or ``on_floor``), a kill at a seeded time between ``window`` (fractions of ``alarm_after_s``)
    after the receipt, so before the alarm is due. The first one kills the publisher (where the detector and
    its open fall live); the others a random stage."""

    alarm_after_s: float
    share: float
    seed: int
    window: tuple[float, float] = (0.05, 0.15)     # early: a fall of the replay may recover within 2 s
    stages: tuple[str, ...] = ("capture", "landmarks", "fitting", "publisher")
    seen: set = field(default_factory=set)
    planned: list = field(default_factory=list)      # (monotonic time, event id, stage)
    n_planned: int = 0

    def __post_init__(self) -> None:
        self._rng = random.Random(self.seed)

    def offer(self, received: dict[tuple[str, str], float], now: float) -> None:
        """Plan kills for the events first received since the last call (``received``: (id, state) -> monotonic
        receipt time); an event received longer ago than the window's start is not planned."""
        for (event_id, state), t in list(received.items()):
            if state not in OPENING or event_id in self.seen:
                continue
            self.seen.add(event_id)
            if self.share <= 0 or self._rng.random() >= self.share:
                continue
            at = t + self._rng.uniform(*self.window) * self.alarm_after_s
            if at < now:
                continue
            stage = "publisher" if not self.n_planned else self._rng.choice(self.stages)
            self.n_planned += 1
            self.planned.append((at, event_id, stage))

    def due(self, now: float) -> list[tuple[str, str]]:
        """The (event id, stage) kills due at ``now``, removed from the plan."""
        out = [(e, s) for at, e, s in self.planned if at <= now]
        self.planned = [p for p in self.planned if p[0] > now]
        return out
