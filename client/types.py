"""What the client hands out: posed's messages decoded into the project's own types.

* pose -> :class:`fitting.FitResult` (``extra`` keeps the message's other fields: ``time_unix``, ``robot``,
  ``image_size``, ``timing_ms``, ``root_cam_m``, ``format``, ``version`` ...);
* fall event -> :class:`falls.FallEvent` (``extra`` keeps ``time_unix``, ``t_onset_unix``, ``t_impact_unix``,
  ``restored``, ``without_frames_s``: read them typed with :func:`restored` and :func:`without_frames_s`);
* status -> :class:`Status` (``raw`` keeps the whole object; ``restored_open``, ``watch``, ``presence`` and
  ``privacy`` typed, ``not_watching``); :func:`presence_note` and :func:`presence_change` say its ``presence``
  in words (``posed watch`` and the web page use them);
* a pause for privacy (the reply to ``PosedClient.pause``/``resume``) -> :class:`PrivacyState`;
* landmarks -> :class:`Landmarks`: ``points``, ``depth_m``, ``world``, ``people`` (each a
  :class:`PersonLandmarks`), ``gravity``, ``floor``, and ``raw``, the whole object as received;
* a stored event -> :class:`HistoryEntry`; a state reply -> :class:`State` (``raw`` keeps the whole object).

Nothing on the wire is lost: a field the client does not know stays in ``extra`` or ``raw`` (docs/formats.md).

Capture-clock times (``t``, ``t_detect``...) are seconds on the robot's monotonic clock; compare robots by
``time_unix``. Decoding raises ``ValueError`` naming what is wrong.
"""

from __future__ import annotations

import datetime as dt
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from posed.falls import FallEvent
from posed.fitting import FitResult
from posed.landmarks.recording import LandmarkFrame, PersonLandmarks

N_LANDMARKS = 33
DELIVERY_FIELDS = ("published_at", "acked_at", "acked_by", "hooks_done_at", "hooks_outcome")   # history replies


def loads(payload: bytes | str) -> dict:
    """One message's JSON object; ValueError when it is not one."""
    try:
        obj = json.loads(payload)
    except ValueError as exc:
        raise ValueError(f"not JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise ValueError(f"a posed message is a JSON object, got {type(obj).__name__}")
    return obj


def robot_of(key: str) -> str:
    """ROBOT in ``posed/ROBOT/...``."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != "posed":
        raise ValueError(f"{key!r} is not a posed key (posed/ROBOT/...)")
    return parts[1]


def time_unix(obj: FitResult | FallEvent) -> float | None:
    """The message's wall-clock time (unix seconds) when it carries one."""
    v = obj.extra.get("time_unix")
    return float(v) if isinstance(v, (int, float)) else None


def decode_pose(obj: dict) -> FitResult:
    return FitResult.from_json(obj)


def decode_event(obj: dict) -> FallEvent:
    try:
        return FallEvent.from_json({k: v for k, v in obj.items() if k not in DELIVERY_FIELDS})
    except (KeyError, TypeError) as exc:
        raise ValueError(f"not a fall event: missing or bad {exc}") from None


def _number(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


@dataclass(frozen=True)
class Restored:
    """A fall event's ``restored``: the daemon (or its publisher) stopped while the fall was open and took it
    back from its journal at ``at_unix``; ``last_state`` its last message before; its alarm due at ``due_unix``
    (docs/falls.md, "The alarm across a restart")."""

    at_unix: float
    last_state: str
    due_unix: float | None
    clock: str | None = None     # "behind" (stepped back), "beyond_horizon": the alarm was due at once (docs/falls.md)


def restored(event: FallEvent) -> Restored | None:
    """The message's ``restored`` typed, None when it has none (or a malformed one)."""
    r = event.extra.get("restored")
    if not isinstance(r, dict) or _number(r.get("at_unix")) is None:
        return None
    return Restored(_number(r.get("at_unix")), str(r.get("last_state") or ""), _number(r.get("due_unix")),
                    _text(r.get("clock")))


def dark_note(camera: Any) -> str:
    """`` (dark: by infrared)`` while a status's ``camera`` (its object) says a RealSense in a dark room watches by
    its infrared image (``spectrum`` infrared; docs/hal.md), else "": what STATUS=, ``posed watch`` and the web
    page add to the camera's state."""
    dark = isinstance(camera, dict) and camera.get("spectrum") == "infrared"
    return " (dark: by infrared)" if dark else ""


def without_frames_s(event: FallEvent) -> float | None:
    """An alarm raised while no camera frame came: seconds since the last frame (None: raised on a frame)."""
    return _number(event.extra.get("without_frames_s"))


@dataclass(frozen=True)
class RestoredFall:
    """One of the status's ``falls.restored_open``: a fall taken back after a restart and still open."""

    id: str
    due_unix: float | None
    alarm: bool
    continued: bool


@dataclass(frozen=True)
class Watch:
    """The status's ``watch``: whether posed is watching, since when (unix seconds) and why not (``reason``: blind,
    waiting_for_camera, degraded, escalated, camera lost, camera ended; ``detail``: what the status said),
    judged by the daemon with the rule of ``hooks.on_watch_lost``."""

    watching: bool
    since_unix: float
    reason: str | None = None
    detail: str | None = None


def _watch(obj: dict) -> Watch | None:
    w = obj.get("watch")
    if not isinstance(w, dict) or not isinstance(w.get("watching"), bool) or _number(w.get("since_unix")) is None:
        return None
    return Watch(w["watching"], _number(w["since_unix"]), _text(w.get("reason")), _text(w.get("detail")))


def _text(v) -> str | None:
    return v if isinstance(v, str) and v else None


@dataclass(frozen=True)
class Presence:
    """The status's ``presence``: when posed last saw the person in its room and whether they have been out of
    view for longer than usual (the absence notice, docs/falls.md). Times in unix seconds on the robot's clock;
    ``absent_s`` the seconds posed WATCHED since ``last_seen_unix`` (time it did not watch adds nothing);
    ``usual_s`` the longest the person was away at this time of day on the ``days`` past days counted (None
    while ``learning``: fewer than ``learn_days`` days counted); ``notice_after_s`` = ``usual_s`` + the margin;
    ``absent`` while the notice runs (given at ``absent_since_unix``); ``in_view``: the person in the latest
    frame."""

    last_seen_unix: float | None
    absent_s: float
    usual_s: float | None
    notice_after_s: float | None
    days: int
    learn_days: int
    learning: bool
    absent: bool
    absent_since_unix: float | None = None
    in_view: bool = False

    @classmethod
    def from_json(cls, p) -> Presence | None:
        """A status's ``presence`` object typed; None when it is null or malformed."""
        if not isinstance(p, dict) or not isinstance(p.get("absent"), bool) \
                or not isinstance(p.get("learning"), bool):
            return None
        absent_s, days, learn_days = _finite(p.get("absent_s")), _count(p.get("days")), _count(p.get("learn_days"))
        if absent_s is None or absent_s < 0 or days is None or learn_days is None:
            return None
        return cls(_finite(p.get("last_seen_unix")), absent_s, _finite(p.get("usual_s")),
                   _finite(p.get("notice_after_s")), days, learn_days, p["learning"], p["absent"],
                   _finite(p.get("absent_since_unix")), p.get("in_view") is True)


def _finite(v) -> float | None:
    n = _number(v)
    return n if n is not None and math.isfinite(n) else None


def _count(v) -> int | None:
    return v if isinstance(v, int) and not isinstance(v, bool) and v >= 0 else None


def _presence(obj: dict) -> Presence | None:
    return Presence.from_json(obj.get("presence"))


def _duration(s: float) -> str:
    """``3 h 10 min``, ``45 min``, ``2 h``; under a minute ``< 1 min`` (whole minutes, rounded down)."""
    m = int(max(0.0, s) // 60) if math.isfinite(s) else 0
    if m < 1:
        return "< 1 min"
    h, m = divmod(m, 60)
    return f"{m} min" if not h else f"{h} h" if not m else f"{h} h {m} min"


def _absence(p: Presence, loud: bool) -> str:
    """``not seen for 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)``
    (``PERSON NOT SEEN FOR ...`` when ``loud``)."""
    out = ("PERSON NOT SEEN FOR " if loud else "not seen for ") + _duration(p.absent_s)
    if p.usual_s is not None:
        days = "the last day" if p.days == 1 else f"any of the last {p.days} days"
        out += f" — longer than on {days} (usually back within {_duration(p.usual_s)})"
    return out


def absence_note(presence: Presence | None) -> str:
    """``PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h
    5 min)`` while the absence notice runs, else "": what STATUS= and ``posed watch`` say."""
    return _absence(presence, loud=True) if presence is not None and presence.absent else ""


def _clock_in(t: float, now_unix: float, zone) -> str:
    """``14:02`` in ``zone`` (an IANA name or a tzinfo; this machine's when None or unknown), dated
    (``2026-12-06 14:02``) when not ``now_unix``'s day there."""
    tz = zone
    if isinstance(zone, str):
        from zoneinfo import ZoneInfo

        try:
            tz = ZoneInfo(zone)
        except (ValueError, KeyError, OSError):     # a zone this machine does not know (ZoneInfoNotFoundError)
            tz = None
    try:
        at, today = dt.datetime.fromtimestamp(t, tz), dt.datetime.fromtimestamp(now_unix, tz)
    except (OverflowError, OSError, ValueError):    # a time no calendar holds
        return "?"
    return at.strftime("%H:%M" if at.date() == today.date() else "%Y-%m-%d %H:%M")


def presence_note(presence: Presence | None, now_unix: float, zone=None) -> str:
    """The status's ``presence`` in words, as the web page shows it (its "person" line) — one of:
    ``in view`` (the person in the latest frame); ``last seen 14:02 (12 min ago)`` (HH:MM in ``zone``, an IANA
    name such as the status's ``time_zone``; this machine's when None); ``not seen yet``; while the absence
    notice runs ``not seen for 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h
    5 min)``; while learning ``; learning the routine: 3 of 7 days`` after it. "" for None (no ``presence``:
    an older posed, or the absence notice off). ``now_unix``: the robot's time now (the status's
    ``time_unix``)."""
    if presence is None:
        return ""
    if presence.absent:
        text = _absence(presence, loud=False)
    elif presence.last_seen_unix is None:
        text = "not seen yet"
    else:
        age = now_unix - presence.last_seen_unix
        text = "in view" if presence.in_view else \
            f"last seen {_clock_in(presence.last_seen_unix, now_unix, zone)} ({_duration(age)} ago)"
    if presence.learning:
        text += f"; learning the routine: {presence.days} of {presence.learn_days} days"
    return text


def presence_change(before: Presence | None, after: Presence | None) -> str | None:
    """What changed from one status's ``presence`` to the next, in words, as ``posed watch`` prints it: the
    absence notice begins (``PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually
    back within 2 h 5 min)``; also for the first status heard when it is absent already, ``before`` None) or
    ends with the person seen again (``person seen again after 3 h 25 min``: from last seen to seen again, by
    the clock); None otherwise (also when a notice ends without the person seen: posed judged again)."""
    if after is None:
        return None
    was = before is not None and before.absent
    if after.absent and not was:
        return absence_note(after)
    if was and not after.absent and after.last_seen_unix is not None and (
            before.last_seen_unix is None or after.last_seen_unix > before.last_seen_unix):
        away = after.last_seen_unix - before.last_seen_unix if before.last_seen_unix is not None \
            else before.absent_s
        return f"person seen again after {_duration(away)}"
    return None


@dataclass(frozen=True)
class PrivacyState:
    """A robot's pause for privacy: the reply to a pause or resume (``posed.privacy``, :meth:`PosedClient.pause`)
    or the status's ``privacy`` (:attr:`Status.privacy`). Times in unix seconds; ``since_unix``, ``until_unix``
    and ``by`` (who asked; None when not said) are None while not paused; ``clamped``: the pause asked for was
    longer than ``max_pause_s`` (the robot's ``privacy.max_pause_s``) and was cut to it; ``remaining_s`` seconds
    left when the message was made. ``raw``: the whole object (``last``, the last pause that ended, in a status)."""

    robot: str
    paused: bool
    since_unix: float | None
    until_unix: float | None
    by: str | None
    clamped: bool = False
    max_pause_s: float | None = None
    remaining_s: float | None = None
    raw: dict = field(repr=False, default_factory=dict)

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> PrivacyState:
        if not isinstance(obj.get("paused"), bool):
            raise ValueError("not a pause for privacy: no boolean 'paused'")
        return cls(str(obj.get("robot") or robot), obj["paused"], _number(obj.get("since_unix")),
                   _number(obj.get("until_unix")), _text(obj.get("by")), obj.get("clamped") is True,
                   _number(obj.get("max_pause_s")), _number(obj.get("remaining_s")), obj)


# the daemon's rule for "posed is not watching" (daemon.outbox.watch_hooks.judge, hooks.on_watch_lost), for a
# status without ``watch`` (an older posed, or one still starting)
NOT_WATCHING_STATES = ("blind", "waiting_for_camera", "degraded", "escalated", "paused")
CAMERA_GONE = ("lost", "ended")


@dataclass(frozen=True)
class Status:
    """A robot's health (posed/ROBOT/status): the fields most readers need, and the whole object in ``raw``."""

    robot: str
    state: str
    time_unix: float | None
    fps: float | None
    latency_p95_ms: float | None
    drops: int
    restarts: int
    camera: str
    unacknowledged_events: int | None
    raw: dict = field(repr=False, default_factory=dict)
    restored_open: tuple[RestoredFall, ...] = ()
    watch: Watch | None = None
    presence: Presence | None = None     # the status's ``presence`` typed (None: not said, null or malformed)

    @property
    def not_watching(self) -> str | None:
        """Why posed cannot see a fall now (the state — blind, waiting_for_camera, degraded, escalated, paused — or
        the camera lost or ended), None while it watches: the status's ``watch`` as the daemon judged it; for a
        status without one (an older posed, or one still starting) the daemon's ``hooks.on_watch_lost`` rule
        judged on this one status (``starting`` and ``stopping`` count as watching there)."""
        if self.watch is not None:
            return None if self.watch.watching else (self.watch.reason or "not watching")
        if self.state in NOT_WATCHING_STATES:
            return self.state
        if self.camera in CAMERA_GONE:
            return f"camera {self.camera}"
        return None

    @property
    def privacy(self) -> PrivacyState | None:
        """The robot's pause for privacy (the status's ``privacy``; state ``paused`` while one runs), None from a
        posed without it."""
        obj = self.raw.get("privacy") if isinstance(self.raw, dict) else None
        try:
            return PrivacyState.from_json(obj, self.robot) if isinstance(obj, dict) else None
        except ValueError:
            return None

    @property
    def robot_id_conflict(self) -> tuple[str, ...]:
        """The other posed daemons on the network that use this robot's id too (each "pid N on host H (Zenoh id
        Z)"), as this daemon sees them (the status's ``zenoh.robot_id_conflict``); empty when none, or from a posed
        before this field. Their messages are mixed with this robot's until one is given another robot_id."""
        zenoh = self.raw.get("zenoh") if isinstance(self.raw, dict) else None
        conflict = zenoh.get("robot_id_conflict") if isinstance(zenoh, dict) else None
        others = conflict.get("other_daemons") if isinstance(conflict, dict) else None
        return tuple(str(o) for o in others) if isinstance(others, list) else ()

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> Status:
        if "state" not in obj:
            raise ValueError("not a status: no 'state'")
        return cls(robot=str(obj.get("robot") or robot), state=str(obj["state"]), time_unix=obj.get("time_unix"),
                   fps=obj.get("fps"), latency_p95_ms=(obj.get("latency_ms") or {}).get("p95"),
                   drops=int(obj.get("drops") or 0), restarts=int(obj.get("restarts") or 0),
                   camera=str((obj.get("camera") or {}).get("state", "")),
                   unacknowledged_events=(obj.get("events") or {}).get("unacknowledged"), raw=obj,
                   restored_open=_restored_open(obj), watch=_watch(obj),
                   presence=_presence(obj))


def _restored_open(obj: dict) -> tuple[RestoredFall, ...]:
    falls = obj.get("falls")
    items = falls.get("restored_open") if isinstance(falls, dict) else None
    return tuple(RestoredFall(str(i["id"]), _number(i.get("due_unix")), i.get("alarm") is True,
                              i.get("continued") is True)
                 for i in (items if isinstance(items, list) else ()) if isinstance(i, dict) and "id" in i)


@dataclass(frozen=True)
class Landmarks:
    """One frame's landmarks (posed/ROBOT/landmarks, docs/formats.md ``posed.landmarks_frame``).

    ``points`` 33×5 float64 [x px, y px, z, visibility, presence] in MediaPipe Pose order, NaN rows unknown;
    None when no person. ``depth_m`` (33,) metres or None. ``world`` 33×5 float64 [x m, y m, z m, visibility,
    presence]: BlazePose's own 3D world landmarks (origin at the middle of the hips, x image right, y down, z away
    from the camera), NaN rows unknown; None when the frame has none. ``points``, ``depth_m`` and ``world`` are
    those of one person, the one followed longest. ``people``: with several people in view, every person of
    the frame (:class:`PersonLandmarks`: ``id`` the track id, ``landmarks``, ``world``, ``depth_m``); empty
    with one person or none. ``gravity``: (x, y, z) the direction of gravity (down) in the camera's axes from
    the camera's accelerometer, or None (also when malformed). ``floor``: the floor plane measured in the depth
    image (``height_m``, ``down``, ``tilt_deg``, ... as docs/formats.md), the object as sent, or None.
    ``raw``: the whole message as received (fields this client does not know yet included)."""

    robot: str
    seq: int
    t: float
    time_unix: float | None
    image_size: tuple[int, int]
    points: np.ndarray | None = field(repr=False)
    depth_m: np.ndarray | None = field(repr=False, default=None)
    world: np.ndarray | None = field(repr=False, default=None)
    people: tuple[PersonLandmarks, ...] = ()
    gravity: tuple[float, float, float] | None = None
    floor: dict | None = field(repr=False, default=None)
    raw: dict = field(repr=False, default_factory=dict)

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> Landmarks:
        """Read by the recordings' own parser (``landmarks.LandmarkFrame.from_json``: the same rules for a
        frame on the wire and in a file); a field it does not know stays in ``raw``."""
        frame = LandmarkFrame.from_json(obj)
        floor = obj.get("floor")
        return cls(robot=str(obj.get("robot") or robot), seq=frame.seq, t=frame.t,
                   time_unix=obj.get("time_unix"), image_size=tuple(obj.get("image_size") or (0, 0)),
                   points=frame.landmarks, depth_m=frame.depth_m, world=frame.world, people=frame.people or (),
                   gravity=frame.gravity, floor=floor if isinstance(floor, dict) else None, raw=obj)


@dataclass(frozen=True)
class HistoryEntry:
    """One stored fall-event message from a robot's journal and its delivery state (unix seconds):
    ``acked_by`` who acknowledged it (the ack's ``by``; None when not said or not acknowledged),
    ``hooks_done_at`` and ``hooks_outcome`` when and how the robot's hooks were done with it (None: not yet,
    or a robot whose posed does not say)."""

    event: FallEvent
    published_at: float | None
    acked_at: float | None
    acked_by: str | None = None
    hooks_done_at: float | None = None
    hooks_outcome: str | None = None

    @property
    def robot(self) -> str:
        return self.event.robot

    @classmethod
    def from_json(cls, obj: dict) -> HistoryEntry:
        return cls(decode_event(obj), obj.get("published_at"), obj.get("acked_at"), obj.get("acked_by"),
                   obj.get("hooks_done_at"), obj.get("hooks_outcome"))


@dataclass(frozen=True)
class State:
    """The reply to a state query: the robot's latest pose and status (None until the first of each)."""

    robot: str
    pose: FitResult | None
    status: Status | None
    raw: dict[str, Any] = field(repr=False, default_factory=dict)

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> State:
        robot = str(obj.get("robot") or robot)
        pose, status = obj.get("pose"), obj.get("status")
        return cls(robot, None if pose is None else decode_pose(pose),
                   None if status is None else Status.from_json(status, robot), obj)
