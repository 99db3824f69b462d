"""Small frozen messages the stage processes exchange, and their JSON forms.

Pixels never travel in these: a :class:`FrameRef` names a slot of the shared-memory ring. The capture
timestamp ``t_capture`` (seconds on the daemon's one monotonic clock) travels end to end and is the only
clock used for latency and fall timing.
"""

from __future__ import annotations

import uuid
from dataclasses import asdict, dataclass, field
from typing import Any

STAGES = ("capture", "landmarks", "fitting", "publisher")
FALL_STATES = ("falling", "on_floor", "alarm", "recovered")


@dataclass(frozen=True)
class FrameRef:
    """A captured frame waiting in the shared-memory ring."""

    slot: int
    seq: int
    t_capture: float
    width: int
    height: int
    has_depth: bool = False
    intrinsics: tuple[float, float, float, float] | None = None   # fx, fy, cx, cy in pixels, when known
    t_read: float | None = None   # monotonic time the capture stage read it, set only for unpaced replays
                                  # (whose t_capture follows the recording): latency is measured from it

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, obj: dict) -> FrameRef:
        return cls(**{k: obj[k] for k in ("slot", "seq", "t_capture", "width", "height")},
                   has_depth=bool(obj.get("has_depth", False)))


@dataclass(frozen=True)
class StageHealth:
    """Heartbeat of one stage process: when it last beat and when its current step began (None = idle)."""

    stage: str
    pid: int
    beat: float
    step_started: float | None
    frames: int
    drops: int = 0
    state: str = "running"

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, obj: dict) -> StageHealth:
        return cls(**obj)


@dataclass(frozen=True)
class FallEvent:
    """A fall event and its updates (an update keeps the ``id`` of the event it belongs to).

    Times are capture timestamps in seconds (t_onset: the fall began; t_impact: the body reached the floor;
    t_detect: the detector decided). ``features`` lists what fired, ``pose`` is the last fit result JSON.
    """

    id: str
    robot: str
    state: str
    t_onset: float | None
    t_impact: float | None
    t_detect: float
    confidence: float
    features: tuple[str, ...] = ()
    pose: dict | None = None
    wall_time: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    @staticmethod
    def new_id() -> str:
        return uuid.uuid4().hex

    def to_json(self) -> dict:
        out = {"id": self.id, "robot": self.robot, "state": self.state, "t_onset": self.t_onset,
               "t_impact": self.t_impact, "t_detect": self.t_detect, "confidence": self.confidence,
               "features": list(self.features), "pose": self.pose, "wall_time": self.wall_time}
        for k, v in self.extra.items():
            out.setdefault(k, v)
        return out

    @classmethod
    def from_json(cls, obj: dict) -> FallEvent:
        if obj.get("state") not in FALL_STATES:
            raise ValueError(f"state {obj.get('state')!r} is not one of: {', '.join(FALL_STATES)}")
        known = {"id", "robot", "state", "t_onset", "t_impact", "t_detect", "confidence", "features", "pose",
                 "wall_time"}
        return cls(id=str(obj["id"]), robot=str(obj["robot"]), state=obj["state"], t_onset=obj.get("t_onset"),
                   t_impact=obj.get("t_impact"), t_detect=float(obj["t_detect"]),
                   confidence=float(obj["confidence"]), features=tuple(obj.get("features") or ()),
                   pose=obj.get("pose"), wall_time=str(obj.get("wall_time", "")),
                   extra={k: v for k, v in obj.items() if k not in known})
