"""A fall event and its updates, and its JSON form (interfaces.md, docs/falls.md).

States in order: ``falling`` (a fall is under way), ``on_floor`` (the person is down), ``alarm`` (down too
long), ``recovered`` (up again). Times are capture timestamps, seconds on the daemon's monotonic clock.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass, field
from typing import Any

FALL_STATES = ("falling", "on_floor", "alarm", "recovered")


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
