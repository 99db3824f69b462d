"""What the client hands out: posed's messages decoded into the project's own types.

* pose -> :class:`fitting.FitResult` (``extra`` keeps the message's other fields: ``time_unix``, ``robot``,
  ``image_size``, ``timing_ms``, ``root_cam_m``, ``format``, ``version`` ...);
* fall event -> :class:`falls.FallEvent` (``extra`` keeps ``time_unix``, ``t_onset_unix``, ``t_impact_unix``);
* status -> :class:`Status` (``raw`` keeps the whole object);
* landmarks -> :class:`Landmarks`: ``points``, ``depth_m``, ``world``, ``people`` (each a
  :class:`PersonLandmarks`), ``gravity``, ``floor``, and ``raw``, the whole object as received;
* a stored event -> :class:`HistoryEntry`; a state reply -> :class:`State` (``raw`` keeps the whole object).

Nothing on the wire is lost: a field the client does not know stays in ``extra`` or ``raw`` (docs/formats.md).

Capture-clock times (``t``, ``t_detect``...) are seconds on the robot's monotonic clock; compare robots by
``time_unix``. Decoding raises ``ValueError`` naming what is wrong.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from posed.falls import FallEvent
from posed.fitting import FitResult

N_LANDMARKS = 33
DELIVERY_FIELDS = ("published_at", "acked_at")


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

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> Status:
        if "state" not in obj:
            raise ValueError("not a status: no 'state'")
        return cls(robot=str(obj.get("robot") or robot), state=str(obj["state"]), time_unix=obj.get("time_unix"),
                   fps=obj.get("fps"), latency_p95_ms=(obj.get("latency_ms") or {}).get("p95"),
                   drops=int(obj.get("drops") or 0), restarts=int(obj.get("restarts") or 0),
                   camera=str((obj.get("camera") or {}).get("state", "")),
                   unacknowledged_events=(obj.get("events") or {}).get("unacknowledged"), raw=obj)


def _rows(raw: Any, key: str) -> np.ndarray | None:
    """A frame's (or person's) ``landmarks`` or ``world``: 33 entries ``[x, y, z, visibility, presence]`` or null,
    as (33, 5) float64 with NaN rows; None when absent or null."""
    if raw is None:
        return None
    if not isinstance(raw, list) or len(raw) != N_LANDMARKS:
        n = len(raw) if isinstance(raw, list) else type(raw).__name__
        raise ValueError(f"{key}: {n} entries, expected {N_LANDMARKS}")
    try:
        return np.array([r if r is not None else [math.nan] * 5 for r in raw], dtype=np.float64).reshape(
            N_LANDMARKS, 5)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: each entry must be [x, y, z, visibility, presence] or null") from None


def _depths(raw: Any, key: str) -> np.ndarray | None:
    """``depth_m``: 33 metres or null each, as (33,) float64 with NaN; None when absent or null."""
    if raw is None:
        return None
    try:
        return np.array([math.nan if d is None else d for d in raw], dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: 33 depths in metres or null") from None


def _gravity(raw: Any) -> tuple[float, float, float] | None:
    """Three finite numbers, not all zero; None for anything else (kept in ``raw``, never used: docs/formats.md)."""
    if not isinstance(raw, (list, tuple)) or len(raw) != 3 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in raw):
        return None
    g = (float(raw[0]), float(raw[1]), float(raw[2]))
    return g if any(g) else None


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    return a is None and b is None or (a is not None and b is not None and np.array_equal(a, b, equal_nan=True))


@dataclass(frozen=True, eq=False)
class PersonLandmarks:
    """One person of a frame's ``people`` (several people in view): ``id`` the track id, stable while the person
    stays in view; ``landmarks`` (33, 5) float64 [x px, y px, z, visibility, presence], NaN rows unknown;
    ``world`` (33, 5) [x m, y m, z m, visibility, presence] BlazePose's world landmarks (hip-centred) or None;
    ``depth_m`` (33,) metres or None; ``raw`` the person's object as received. Equal when the values are."""

    id: int
    landmarks: np.ndarray = field(repr=False)
    world: np.ndarray | None = field(repr=False, default=None)
    depth_m: np.ndarray | None = field(repr=False, default=None)
    raw: dict = field(repr=False, default_factory=dict)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PersonLandmarks):
            return NotImplemented
        return self.id == other.id and all(_same(getattr(self, k), getattr(other, k))
                                           for k in ("landmarks", "world", "depth_m"))

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def from_json(cls, obj: Any, index: int = 0) -> PersonLandmarks:
        key = f"people[{index}]"
        if not isinstance(obj, dict):
            raise ValueError(f"{key}: a person is an object {{id, landmarks, world, depth_m}}")
        pid = obj.get("id")
        if not isinstance(pid, int) or isinstance(pid, bool) or pid < 0:
            raise ValueError(f"{key}: id must be a non-negative integer (a track id), got {pid!r}")
        landmarks = _rows(obj.get("landmarks"), f"{key}.landmarks")
        if landmarks is None:
            raise ValueError(f"{key}: no landmarks")
        return cls(id=pid, landmarks=landmarks, world=_rows(obj.get("world"), f"{key}.world"),
                   depth_m=_depths(obj.get("depth_m"), f"{key}.depth_m"), raw=obj)


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
        people = obj.get("people")
        if people is not None and not isinstance(people, list):
            raise ValueError(f"people: a list of persons, got {type(people).__name__}")
        floor = obj.get("floor")
        return cls(robot=str(obj.get("robot") or robot), seq=int(obj["seq"]), t=float(obj["t"]),
                   time_unix=obj.get("time_unix"), image_size=tuple(obj.get("image_size") or (0, 0)),
                   points=_rows(obj.get("landmarks"), "landmarks"),
                   depth_m=_depths(obj.get("depth_m"), "depth_m"),
                   world=_rows(obj.get("world"), "world"),
                   people=tuple(PersonLandmarks.from_json(p, i) for i, p in enumerate(people or ())),
                   gravity=_gravity(obj.get("gravity")),
                   floor=floor if isinstance(floor, dict) else None, raw=obj)


@dataclass(frozen=True)
class HistoryEntry:
    """One stored fall-event message from a robot's journal and its delivery state (unix seconds)."""

    event: FallEvent
    published_at: float | None
    acked_at: float | None

    @property
    def robot(self) -> str:
        return self.event.robot

    @classmethod
    def from_json(cls, obj: dict) -> HistoryEntry:
        return cls(decode_event(obj), obj.get("published_at"), obj.get("acked_at"))


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
