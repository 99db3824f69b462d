"""What the client hands out: posed's messages decoded into the project's own types.

* pose -> :class:`fitting.FitResult` (``extra`` keeps the message's other fields: ``time_unix``, ``robot``,
  ``image_size``, ``timing_ms``, ``root_cam_m``, ``format``, ``version`` ...);
* fall event -> :class:`falls.FallEvent` (``extra`` keeps ``time_unix``, ``t_onset_unix``, ``t_impact_unix``);
* status -> :class:`Status`; landmarks -> :class:`Landmarks`; a stored event -> :class:`HistoryEntry`.

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


@dataclass(frozen=True)
class Landmarks:
    """One frame's 2D landmarks (posed/ROBOT/landmarks): ``points`` 33×5 float64 [x px, y px, z, visibility,
    presence] in MediaPipe Pose order, NaN rows unknown; None when no person. ``depth_m`` (33,) metres or None."""

    robot: str
    seq: int
    t: float
    time_unix: float | None
    image_size: tuple[int, int]
    points: np.ndarray | None = field(repr=False)
    depth_m: np.ndarray | None = field(repr=False, default=None)

    @classmethod
    def from_json(cls, obj: dict, robot: str = "") -> Landmarks:
        rows = obj.get("landmarks")
        points = None
        if rows is not None:
            if len(rows) != N_LANDMARKS:
                raise ValueError(f"landmarks: {len(rows)} entries, expected {N_LANDMARKS}")
            points = np.array([r if r is not None else [math.nan] * 5 for r in rows], dtype=np.float64)
        depth = obj.get("depth_m")
        return cls(robot=str(obj.get("robot") or robot), seq=int(obj["seq"]), t=float(obj["t"]),
                   time_unix=obj.get("time_unix"), image_size=tuple(obj.get("image_size") or (0, 0)),
                   points=points,
                   depth_m=None if depth is None else np.array([math.nan if d is None else d for d in depth]))


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
