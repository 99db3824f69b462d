"""Falls open at a restart: taken back from the event journal, their alarm kept (docs/falls.md, "The alarm across
a restart").

The detector's event under way lives in the publisher's memory. When the daemon, or only its publisher stage,
is killed after ``falling`` or ``on_floor`` and before ``alarm``, the fresh detector knows nothing of it. So at
the publisher's start :meth:`RestoredFalls.load` reads the journal (every message, oldest first; the journal
keeps every message and has no retention of its own): an event none of whose messages is an ``alarm`` or a
``recovered`` is **open**. An open fall whose impact is at most :data:`RESTORE_HORIZON_S` old is re-armed with
its own id: its alarm is due at ``t_impact_unix + falls.alarm_after_s`` in unix time, put on this boot's
monotonic clock when it is read (``due - now_unix + now``), so a reboot (the monotonic clock starting again)
changes nothing. Older open falls that a receiver acknowledged are not re-armed and are logged
(``open_falls_not_restored``) at every start; older ones nobody acknowledged, and any fall when the clock was
stepped back since it was journalled, are alarmed at once (``_open_fall``: rather early than never).

- **The alarm.** Raised when due (:meth:`RestoredFalls.due`, called between frames, frames or none); one
  already past due at once, on the stage's first tick after its warm-up. Raised while no frame has come for the
  blind threshold, it carries ``without_frames_s`` as the detector's alarm without frames does. Its content is the detector's alarm
  for that event: the same id, robot, ``t_onset`` and ``t_impact`` (as stored: the capture clock of the run
  that raised it) with ``t_onset_unix`` and ``t_impact_unix`` as stored, the first message's features plus
  ``not_recovered``, its confidence (at least 0.9), the last message's pose, person and geometry; ``t_detect``
  is now. Every message of a restored event carries ``restored``: ``{"at_unix": when it was taken back,
  "last_state": its last message before the restart, "due_unix": when its alarm is due}``.
- **Found lying again.** While a restored fall is open and nobody has been seen up since the start (the
  recovery rule below, by anyone), a new event the fresh detector raises for a person found lying (``on_floor``
  with ``lying_at_floor_level``, never seen up before: ``t_onset`` None, no descent seen: not
  ``controlled_descent``) is that fall, not a second one: the detector continues the restored event
  (:meth:`falls.detector.FallDetector.continue_event`: its id, times, features; the alarm due when it was, on
  the frames' clock), the new id is never published, and its ``on_floor`` goes out only when the restored
  event had none (then as that event's, with ``still_on_floor``). Recovery is then the detector's own, for
  the person it follows. A fall seen (``falling``) is always a new event.
- **Recovered.** Without such a person, a restored fall is recovered only on clear evidence: exactly one
  restored fall open, exactly one person in view (landmarks) on every frame for ``falls.recover_s``, judged up
  by the detector's recovery rule on those frames (:attr:`FallDetector.judged_up`; frames not judged change
  nothing, as missing frames are no evidence of recovery, up to ``falls.max_gap_s``), and with
  ``falls.household`` configured, that person recognised as a member. Otherwise the alarm stands.
- An acknowledgement changes none of this: the detector's alarm is not cancelled by one either.
- The detector that continues a restored fall may lose it (a stream restarted, a person forgotten): the alarm
  then falls back here and is raised when due.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from posed.daemon.clock import iso
from posed.daemon.stages.fall_watch import _people
from posed.daemon.timeparse import FUTURE_SLACK_S
from posed.falls import FallEvent, FallsConfig

RESTORE_HORIZON_S = 24 * 3600.0
# A day. Within it an open fall is re-armed whatever the downtime. Beyond it (the daemon, or the robot, down
# for more than a day after a fall, a fall left open by a posed without this restore, or a unix clock stepped
# forward since) an acknowledged fall is known to someone: it stays in the journal as it was and is named in the
# log at every start. One nobody acknowledged is alarmed at once, once: the age may be the clock's error.
CLOCK_SLACK_S = FUTURE_SLACK_S
# How far the clock now may be earlier than a time the fall was journalled at before it counts as stepped back:
# NTP slews small errors (at most 0.5 ms/s) and steps only large ones (the views' "stamped later than now" alike).
STAMPED = ("format", "version", "time_unix")      # made anew for each message (payloads.stamp_event)
PERSON_KEYS = ("person", "root_cam_m", "person_match", "member", "household")
STATE_ORDER = {"falling": 0, "on_floor": 1, "alarm": 2, "recovered": 3}


@dataclass
class OpenFall:
    """One fall taken back from the journal."""

    id: str
    robot: str
    t_onset: float | None          # as stored: the capture clock of the run that raised it
    t_impact: float | None
    t_impact_unix: float
    due_unix: float
    due: float                     # the alarm's due time on this boot's monotonic clock
    features: tuple[str, ...]      # the first message's
    confidence: float
    geometry: dict
    sent: set[str]
    pose: dict | None              # the last message's
    last_extra: dict               # the last message's extra fields (person, pelvis height, geometry ...)
    carried: dict                  # what every later message carries: t_onset_unix, t_impact_unix, restored
    handed: bool = False           # a detector continues it (a person found lying: module doc)
    closed: bool = False
    clock: str | None = None       # "behind", "beyond_horizon": alarm due at once (_open_fall)

    @property
    def open(self) -> bool:
        return not self.closed

    def message(self, state: str, t_detect: float, confidence: float, features: tuple[str, ...],
                pose: dict | None, extra: dict) -> FallEvent:
        """A message of this fall (its id, robot, ``t_onset`` and ``t_impact`` as stored), ``extra`` with what
        every message of it carries (``carried``: the unix times, ``restored``) laid over."""
        return FallEvent(id=self.id, robot=self.robot, state=state, t_onset=self.t_onset, t_impact=self.t_impact,
                         t_detect=t_detect, confidence=confidence, features=features, pose=pose,
                         extra={**extra, **self.carried})


class RestoredFalls:
    """The open falls of the runs before; ``due`` between frames, ``frame`` after each frame's detection."""

    def __init__(self, falls: list[OpenFall], cfg: FallsConfig, log) -> None:
        self.falls = falls
        self.cfg = cfg
        self.log = log
        self.seen_up_at: float | None = None      # capture time someone was first seen up since the start
        self._up: dict = {}                       # person -> up since (capture time)
        self._judged: dict = {}                   # person -> last judged (capture time)
        self._alone_since: float | None = None    # at most one person in view since

    # ------------------------------------------------------------------ reading the journal

    @classmethod
    def load(cls, journal, cfg: FallsConfig, log, now: float | None = None, now_unix: float | None = None,
             horizon_s: float = RESTORE_HORIZON_S) -> RestoredFalls:
        """The open falls in ``journal`` (an :class:`daemon.outbox.journal.EventJournal`), re-armed against
        ``now`` (monotonic) and ``now_unix`` (default: the clocks now)."""
        now = time.monotonic() if now is None else now
        now_unix = time.time() if now_unix is None else now_unix
        by_id: dict[str, list] = {}
        try:
            messages = journal.query()
        except Exception as exc:       # an unreadable journal must not stop the stage (and detection) for good
            log.error("open_falls_unreadable", error=repr(exc), journal=str(getattr(journal, "path", "")),
                      note="the falls left open by the run before cannot be read: their alarms are not kept",
                      fix="look at the journal with posed events; a corrupt file is set aside at the next start")
            return cls([], cfg, log)
        for stored in messages:
            by_id.setdefault(stored.event.id, []).append(stored)
        falls, old = [], []
        for event_id, items in by_id.items():
            states = {s.event.state for s in items}
            if "alarm" in states or "recovered" in states:
                continue
            try:
                fall = _open_fall(event_id, items, cfg, now, now_unix, horizon_s)
            except Exception as exc:   # a damaged message must not cost the other falls (nor the stage)
                log.error("open_fall_unreadable", id=event_id, error=repr(exc),
                          note="a fall left open by the run before whose messages cannot be read: its alarm is "
                               "not kept; the other falls are",
                          fix="look at it: posed events --json --since 2d; acknowledge it when it is known")
                continue
            if fall is None:
                old.append((_impact_unix(items[0]), event_id))
                continue
            falls.append(fall)
            _log_restored(log, fall, now_unix)
        if old:
            old.sort()
            log.warning("open_falls_not_restored", count=len(old), ids=[i for _, i in old[-10:]],
                        oldest=iso(old[0][0]), newest=iso(old[-1][0]), horizon_h=round(horizon_s / 3600.0, 1),
                        note="falls never alarmed nor recovered, acknowledged by a receiver, their impact longer "
                             "ago than the horizon: no alarm is raised for them now; they stay in the journal as "
                             "they are",
                        fix="look at them (posed events --since 30d) and acknowledge them (posed events ack ID)")
        falls.sort(key=lambda f: f.due)
        return cls(falls, cfg, log)

    @property
    def open(self) -> list[OpenFall]:
        return [f for f in self.falls if f.open]

    def status(self) -> list[dict]:
        """For the status object: each restored fall still open."""
        return [{"id": f.id, "due_unix": round(f.due_unix, 3), "alarm": "alarm" in f.sent,
                 "continued": f.handed} for f in self.open]

    # ------------------------------------------------------------------ the alarm

    def due(self, now: float, watch=None, without_frames_s: float | None = None) -> list[FallEvent]:
        """The alarms due at ``now`` (monotonic) of the restored falls kept here (not continued by a detector
        that still has them: ``watch`` is the stage's :class:`FallWatch`). ``without_frames_s``: no frame has
        come for that long (at least the blind threshold; None: frames come); an alarm raised then carries it,
        as the detector's own alarm without frames does (:meth:`FallWatch.tick`)."""
        out = []
        for f in self.open:
            if "alarm" in f.sent:
                continue
            if f.handed and _holder(watch, f.id) is not None:
                continue
            if f.handed:                      # the detector lost it: the alarm is kept here again
                f.handed = False
                self.log.warning("restored_fall_taken_back", id=f.id,
                                 note="the detector that continued a restored fall lost it; its alarm is kept")
            if now < f.due - 1e-9:
                continue
            extra = dict(f.last_extra)
            if without_frames_s is not None:
                extra["without_frames_s"] = round(float(without_frames_s), 3)
            out.append(f.message("alarm", now, round(max(f.confidence, 0.9), 3), f.features + ("not_recovered",),
                                 f.pose, extra))
            f.sent.add("alarm")
        return out

    # ------------------------------------------------------------------ frames

    def frame(self, msg, watch, events: list[FallEvent], now: float) -> list[FallEvent]:
        """After the detection of one frame (``events`` its messages, ``watch`` the :class:`FallWatch` that
        judged it, ``now`` monotonic): a person found lying is attributed to an open restored fall; the
        recovery evidence is gathered. Returns the messages to send."""
        if not self.falls or watch is None or watch.people is None:
            return events
        if not any(f.open for f in self.falls):
            return events
        t = float(msg.result.t)
        self.observe(events)
        self._gather(msg, watch, t)
        out = []
        for e in events:
            target = self._attribution(e)
            if target is None:
                out.append(e)
                continue
            out += self._continue(target, e, watch, now)
        out += self._recovery(watch, t)
        return out

    def observe(self, events: list[FallEvent]) -> None:
        """Messages sent for restored falls (by the detectors that continue them)."""
        for e in events:
            f = self._by_id(e.id)
            if f is None:
                continue
            f.sent.add(e.state)
            if e.state == "recovered":
                f.closed = True
                self.log.info("restored_fall_recovered", id=f.id, by="detector")

    def _by_id(self, event_id: str) -> OpenFall | None:
        return next((f for f in self.falls if f.id == event_id), None)

    def _attribution(self, e: FallEvent) -> OpenFall | None:
        """The open restored fall a new found-lying event belongs to (module doc), or None."""
        if e.state != "on_floor" or e.features[:1] != ("lying_at_floor_level",) or e.t_onset is not None \
                or "controlled_descent" in e.features or self.seen_up_at is not None:
            return None
        if self._by_id(e.id) is not None:
            return None
        free = [f for f in self.open if not f.handed]
        return free[-1] if free else None     # the latest due: the most recent fall

    def _continue(self, f: OpenFall, e: FallEvent, watch, now: float) -> list[FallEvent]:
        found = watch.people.detector_of(e.id)
        if found is None:
            return [e]
        key, det = found
        # the alarm's due time on the frames' clock: the capture clock is the monotonic one (live, paced
        # replays) or runs ahead of it (unpaced replays), never behind
        due_t = f.due + max(0.0, e.t_detect - now)
        sent = f.sent | {"on_floor"}
        det.continue_event(f.id, f.t_onset, f.t_impact, due_t, f.features, f.confidence, f.geometry, sent,
                           f.carried)
        f.handed = True
        self.log.info("restored_fall_found_lying", id=f.id, new_id=e.id, person=key, alarm_sent="alarm" in f.sent,
                      note="a person found lying while a fall restored after a restart was open: that fall, "
                           "not a new one")
        if "on_floor" in f.sent:
            return []
        f.sent.add("on_floor")
        return [f.message("on_floor", e.t_detect, f.confidence, f.features + ("still_on_floor",), e.pose,
                          {**e.extra, "geometry": dict(f.geometry)})]

    def _gather(self, msg, watch, t: float) -> None:
        """Who is in view and who is judged up (the detector's recovery rule), per person."""
        people = watch.people
        in_view = sum(1 for _, _, lm in _people(msg) if lm is not None)
        if in_view >= 2:
            self._alone_since = None
        elif self._alone_since is None:
            self._alone_since = t
        for key in people.in_frame:
            person = people.people.get(key)
            up = person.detector.judged_up if person is not None else None
            if up is None:
                continue
            self._judged[key] = t
            self._up[key] = (self._up.get(key) or t) if up else None
        for key, last in list(self._judged.items()):
            if t - last > self.cfg.max_gap_s:
                self._judged.pop(key)
                self._up.pop(key, None)
        if self.seen_up_at is None and any(s is not None and t - s >= self.cfg.recover_s - 1e-9
                                           for s in self._up.values()):
            self.seen_up_at = t

    def _recovery(self, watch, t: float) -> list[FallEvent]:
        """Recovered on clear evidence (module doc)."""
        still = self.open
        if len(still) != 1 or still[0].handed or self._alone_since is None:
            return []
        up = [(k, s) for k, s in self._up.items() if s is not None]
        if len(up) != 1:
            return []
        key, since = up[0]
        if t - max(since, self._alone_since) < self.cfg.recover_s - 1e-9:
            return []
        people = watch.people
        if people.household and people.household.rank(key) is None:
            return []            # with a household: only a member recognised seen up is the person who fell
        f = still[0]
        person = people.people[key]
        det = person.detector
        extra = {k: v for k, v in f.last_extra.items() if k not in PERSON_KEYS}
        s = det.last_sample
        if s is not None:
            extra.update(pelvis_height_rel=round(s.h_rel, 3), trunk_inclination_deg=round(s.incl, 1))
        if key is not None:
            extra["person"] = key
            extra["root_cam_m"] = None if person.root_cam_m is None else [round(float(v), 3)
                                                                          for v in person.root_cam_m]
        result = people.in_frame.get(key)
        f.sent.add("recovered")
        f.closed = True
        self.log.info("restored_fall_recovered", id=f.id, by="seen_up", person=key, alarm_sent="alarm" in f.sent)
        return [f.message("recovered", t, 0.9, ("up_again",), result.to_json() if result is not None else None,
                          extra)]


def _open_fall(event_id: str, items: list, cfg: FallsConfig, now: float, now_unix: float,
               horizon_s: float) -> OpenFall | None:
    """One open fall re-armed (module doc), or None: older than the horizon and acknowledged by a receiver.

    The unix clock may have been stepped since the fall was journalled (NTP at the boot of a machine without an
    RTC battery, a clock set by hand). Never later than it would be without the step, and rather early than never:

    - the clock now earlier than a time the fall was journalled at (it was stepped back): how long ago the fall
      was is unknown, so its alarm is due at once (``restored.clock``: ``behind``);
    - its impact longer ago than the horizon: a daemon down for that long, or a clock stepped forward (or a fall
      journalled by a clock that was behind). Nobody has acknowledged it: its alarm is due at once
      (``restored.clock``: ``beyond_horizon``), once; acknowledged, someone knows of it: not re-armed."""
    states = {s.event.state for s in items}
    items.sort(key=lambda s: (STATE_ORDER.get(s.event.state, 9), s.wall))
    first, last = items[0], items[-1]
    impact_unix = _impact_unix(first)
    due_unix = impact_unix + cfg.alarm_after_s
    journalled_at = max([impact_unix] + [s.wall for s in items])
    clock = None
    if now_unix < journalled_at - CLOCK_SLACK_S:
        clock = "behind"
    elif now_unix - impact_unix > horizon_s:
        if any(s.acked_at is not None for s in items):
            return None
        clock = "beyond_horizon"
    if clock is not None:
        due_unix = now_unix
    extra = {k: v for k, v in last.event.extra.items() if k not in STAMPED}
    carried = {k: extra[k] for k in ("t_onset_unix", "t_impact_unix") if _is_number(extra.get(k))}
    carried.setdefault("t_impact_unix", round(impact_unix, 4))
    carried["restored"] = {"at_unix": round(now_unix, 3), "last_state": last.event.state,
                           "due_unix": round(due_unix, 3)}
    if clock is not None:
        carried["restored"]["clock"] = clock
    geometry = extra.get("geometry")
    return OpenFall(
        id=event_id, robot=first.event.robot, t_onset=_number(first.event.t_onset),
        t_impact=_number(first.event.t_impact), t_impact_unix=impact_unix, due_unix=due_unix,
        due=due_unix - now_unix + now, features=tuple(str(f) for f in first.event.features),
        confidence=float(first.event.confidence), geometry=dict(geometry) if isinstance(geometry, dict) else {},
        sent=states, pose=last.event.pose if isinstance(last.event.pose, dict) else None, last_extra=extra,
        carried=carried, clock=clock)


def _log_restored(log, fall: OpenFall, now_unix: float) -> None:
    fields = dict(id=fall.id, last_state=fall.carried["restored"]["last_state"], impact=iso(fall.t_impact_unix),
                  alarm_due=iso(fall.due_unix), alarm_in_s=round(max(fall.due_unix - now_unix, 0.0), 3))
    if fall.clock is None:
        log.warning("open_fall_restored", **fields,
                    note="a fall was open when the daemon or its publisher stopped: its alarm is raised when due "
                         "unless the person is clearly seen up")
        return
    age_s = round(now_unix - fall.t_impact_unix, 1)
    why = (f"the clock now ({iso(now_unix)}) is earlier than when the fall was journalled: it was stepped back "
           "(NTP at boot, a clock set by hand), so how long ago the fall was is unknown"
           if fall.clock == "behind" else
           f"its impact is {age_s:g} s ago by this clock, beyond the {RESTORE_HORIZON_S / 3600:g} h horizon, and "
           "nobody acknowledged it: the daemon was down that long, or the clock was stepped forward since")
    log.error("open_fall_restored", **fields, clock=fall.clock, age_s=age_s, reason=why,
              note="its alarm is raised at once, rather than late or never",
              fix="check the system clock (timedatectl; an RTC battery, NTP before posed starts); acknowledge the "
                  "event once the person is found")


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _number(value) -> float | None:
    """A time read from a stored message: a finite number, else None (a damaged field)."""
    return float(value) if _is_number(value) else None


def _impact_unix(stored) -> float:
    """When the fall's impact was, unix seconds: as stamped (``t_impact_unix``); for a message journalled
    without it (or with a damaged one), its journal time less the time from impact to detection."""
    e = stored.event
    value = e.extra.get("t_impact_unix")
    if _is_number(value):
        return float(value)
    t_impact, t_detect = _number(e.t_impact), _number(e.t_detect)
    if t_impact is not None and t_detect is not None:
        return float(stored.wall) - max(0.0, t_detect - t_impact)
    return float(stored.wall)


def _holder(watch, event_id: str):
    if watch is None or watch.people is None:
        return None
    return watch.people.detector_of(event_id)
