"""Joint-angle time series and fall episodes, as the plots and the report take them (plain values, no I/O).

Time is either a clock (unix seconds, shown in the robot's local time zone) or seconds from a recording's
first frame (a fit file carries only capture times). Angles are degrees; NaN means not measured (no fit, or
not measured in that frame by fitting's rule, ``FitResult.measured``) and is never drawn as 0.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from posed.viz.names import FIXED_ANGLES

# a time stamped later than "now" by more than this was stamped by a clock that was wrong then (set right since,
# e.g. by NTP at the boot of a robot without an RTC battery) or is wrong now (daemon.timeparse.FUTURE_SLACK_S)
CLOCK_SLACK_S = 2.0
STAMPED_LATER = ("stamped later than this report was made ({now}): the robot's clock was wrong when it was recorded "
                 "(set right since, e.g. by NTP at boot) or is wrong now; when it really happened is unknown")

# messages of one event, in the order they can happen (falls.FALL_STATES)
STATE_WORDS = {"falling": "fall", "on_floor": "on the floor", "alarm": "ALARM", "recovered": "got up"}


def states_text(states: Sequence[str]) -> str:
    """``fall → on the floor → got up``: a fall's states as the web page words them."""
    return " → ".join(STATE_WORDS.get(s, s.replace("_", " ")) for s in states)


@dataclass(frozen=True)
class AngleSeries:
    """``time`` (N,) seconds, increasing: unix time when ``clock``, else from the first frame; ``angles``:
    name -> (N,) degrees, NaN = not measured."""

    time: np.ndarray
    angles: dict[str, np.ndarray]
    clock: bool

    @classmethod
    def from_rows(cls, wall: Sequence[float], columns: dict[str, Sequence[float | None]]) -> AngleSeries:
        """History rows: unix times and angle columns (None = unknown). The angles the model holds fixed are
        left out (they are constants, not measurements)."""
        t = np.asarray(wall, float)
        angles = {k: np.array([np.nan if v is None else v for v in vals], float)
                  for k, vals in columns.items() if k not in FIXED_ANGLES}
        return cls(t, angles, clock=True)

    @classmethod
    def from_fits(cls, results: Iterable, start_unix: float | None = None) -> AngleSeries:
        """Fit results (``fitting.FitResult``) of a recording: ``t`` from its first frame, or clock times
        ``start_unix + t`` when the recording's start is known. A failed fit is NaN for every angle, and so
        is an angle that frame did not measure (``FitResult.measured``)."""
        results = list(results)
        if not results:
            return cls(np.zeros(0), {}, clock=start_unix is not None)
        t = np.array([r.t for r in results], float)
        names = [n for n in _names(results) if n not in FIXED_ANGLES]
        angles = {n: np.full(len(results), np.nan) for n in names}
        for i, r in enumerate(results):
            if not r.ok:
                continue
            values = r.measured_angles()   # fitting.measured: the rest of the frame is the model's guess
            for n in names:
                if n in values:
                    angles[n][i] = values[n]
        if start_unix is not None:
            return cls(start_unix + (t - t[0]), angles, clock=True)
        return cls(t - t[0], angles, clock=False)

    def with_gaps(self, gap_s: float | None = None) -> AngleSeries:
        """A NaN sample inserted in every gap longer than ``gap_s`` (default: 5 sampling periods, at least 2 s),
        so lines are broken where nothing was recorded."""
        if len(self.time) < 2:
            return self
        dt = np.diff(self.time)
        gap = gap_s if gap_s is not None else max(2.0, 5.0 * float(np.median(dt)))
        cut = np.nonzero(dt > gap)[0]
        if not len(cut):
            return self
        t = np.insert(self.time, cut + 1, self.time[cut] + dt[cut] / 2)
        angles = {k: np.insert(v, cut + 1, np.nan) for k, v in self.angles.items()}
        return AngleSeries(t, angles, self.clock)


@dataclass(frozen=True)
class EventMark:
    """One fall-event message: its event ``id``, ``state`` (falls.FALL_STATES), time (same clock as the
    series) and when it was acknowledged (same clock; None = not)."""

    id: str
    state: str
    time: float
    acked: float | None = None
    who: str | None = None        # whose fall (a household member's name, "a visitor", "person N"), if known
    by: str | None = None         # who acknowledged it (the ack's ``by``), when said
    restored_at: float | None = None        # unix time posed took the open fall back after a restart
    without_frames_s: float | None = None   # an alarm raised with no camera frame for this long


@dataclass(frozen=True)
class Episode:
    """One fall event's messages together: when it started and last changed, its states in order, how it
    ended (``recovered``, ``alarm``, ``on the floor`` or ``falling`` — the last state) and whether someone
    acknowledged it: ``acked`` is when its last message was acknowledged, only once every message is (a later
    state, e.g. the alarm, needs its own acknowledgement); ``unacked`` the states still not acknowledged,
    ``acked_by`` who acknowledged. ``restored_at``: posed restarted while the fall was open and took it back
    from its journal then; ``without_frames_s``: the alarm was raised with no camera frame for that long."""

    id: str
    start: float
    end: float
    states: tuple[str, ...]
    acked: float | None = None
    notes: tuple[str, ...] = field(default=())
    who: str | None = None        # whose fall, when the messages say
    unacked: tuple[str, ...] = ()
    acked_by: tuple[str, ...] = ()
    restored_at: float | None = None
    without_frames_s: float | None = None

    def ack_text(self, fmt) -> str:
        """``acknowledged 14:05:10 by anna``; ``ALARM not acknowledged (fall acknowledged 14:03:30 by anna)``
        when only some messages are; ``not acknowledged``."""
        by = f" by {', '.join(self.acked_by)}" if self.acked_by else ""
        if self.acked is not None:
            return f"acknowledged {fmt(self.acked)}{by}"
        if self.unacked and len(self.unacked) < len(self.states):
            done = [s for s in self.states if s not in self.unacked]
            return f"{states_text(self.unacked)} not acknowledged ({states_text(done)} acknowledged{by})"
        return "not acknowledged"

    def caveats(self, fmt) -> list[str]:
        """What a reader must know beside the states: a fall taken back after a restart, an alarm raised
        while no camera frame came (nobody was seen: the person may have got up unseen, or still lie there)."""
        out = []
        if self.restored_at is not None:
            out.append(f"posed restarted during this fall and took it back at {fmt(self.restored_at)}")
        if self.without_frames_s is not None:
            out.append(f"{STATE_WORDS['alarm']} raised with no camera frame for {self.without_frames_s:.0f} s "
                       "(the camera had stopped: the person was not seen)")
        return out

    def outcome(self, now: float, in_progress_s: float, fmt) -> str:
        """How the fall ended, as of ``now`` (when the view is made): got up, the alarm, in progress (the last
        message is less than ``in_progress_s`` old and neither got up nor the alarm: the detector is still
        timing it), still on the floor when last heard of, or no further message (the person left the view);
        ``fmt`` formats a time."""
        last = self.states[-1] if self.states else ""
        if "recovered" in self.states:
            return STATE_WORDS["recovered"]
        if last == "alarm":
            return f"{STATE_WORDS['alarm']} raised (on the floor too long)"
        if self.end > now + CLOCK_SLACK_S:     # never "in progress", nor a negative time since: a wrong clock
            return f"{STATE_WORDS[last] if last in STATE_WORDS else last}; last message " + \
                STAMPED_LATER.format(now=fmt(now))
        if now - self.end < in_progress_s:
            return f"in progress when this report was made ({fmt(now)})"
        if last == "on_floor":
            return f"{STATE_WORDS['on_floor']}; no recovery seen"
        return "no further message (the person left the view)"

    def describe(self, fmt, acks: bool = True) -> str:
        """One line: ``14:03:05 fall → on the floor → ALARM; acknowledged 14:05:10``; ``fmt`` formats a time;
        ``acks`` False: the source knows nothing of acknowledgements (a ``posed falls`` output)."""
        text = f"{fmt(self.start)} {states_text(self.states)}"
        if acks:
            text += f"; {self.ack_text(fmt)}"
        for note in self.caveats(fmt):
            text += f"; {note}"
        return text


def episodes(marks: Iterable[EventMark]) -> list[Episode]:
    """The fall episodes of these messages, in time order (one per event id)."""
    by_id: dict[str, list[EventMark]] = {}
    for m in sorted(marks, key=lambda m: m.time):
        by_id.setdefault(m.id, []).append(m)
    out = []
    for eid, ms in by_id.items():
        states: list[str] = []
        for m in ms:
            if m.state not in states:
                states.append(m.state)
        acked = [m.acked for m in ms if m.acked is not None]
        unacked = tuple(dict.fromkeys(m.state for m in ms if m.acked is None))
        who = next((m.who for m in reversed(ms) if m.who), None)      # the latest word on it
        by = tuple(dict.fromkeys(m.by for m in ms if m.by and m.acked is not None))
        restored = next((m.restored_at for m in ms if m.restored_at is not None), None)
        blind = next((m.without_frames_s for m in ms if m.without_frames_s is not None), None)
        out.append(Episode(eid, ms[0].time, ms[-1].time, tuple(states), max(acked) if not unacked else None,
                           who=who, unacked=unacked, acked_by=by, restored_at=restored, without_frames_s=blind))
    return sorted(out, key=lambda e: e.start)


def _names(results: list) -> list[str]:
    seen: dict[str, None] = {}
    for r in results:
        if r.ok:
            seen.update(dict.fromkeys(r.joint_angles_deg))
            seen.update(dict.fromkeys(k for k in ("theta_bd", "phi_bd", "psi_bd") if k in r.variables))
    return list(seen)
