"""Fall detection in the publisher stage: the :mod:`falls` detector run on every fit, in capture order.

Every FitMsg is fed (also frames without a person: the alarm timer runs on the capture timestamps, the one
clock), with its 2D landmarks, image size and camera intrinsics. A detector that raises must not stop the
poses: the frame then yields no event, the stage's error counter goes up and the failure is logged (the
first three, then every hundredth).

IMU gravity: a frame whose landmark frame carries ``gravity`` (three numbers, the accelerometer's down
vector in the colour camera's axes, any length: ``LandmarkFrame.gravity``, filled by a RealSense camera or
recording with an accelerometer through hal.imu, or a ``*.landmarks.jsonl`` line's ``"gravity"``) sets the
detector's gravity when ``falls.imu_gravity`` is on. A malformed one (kept in the frame's ``extra``) is
counted and logged, and the gravity in use is kept.
"""

from __future__ import annotations

from collections.abc import Callable

from posed.daemon.messages import FitMsg
from posed.falls import FallDetector, FallEvent, FallsConfig

LOG_FIRST_FAILURES = 3
LOG_FAILURE_EVERY = 100


class FallWatch:
    """Wraps a :class:`FallDetector` (None when ``falls.enabled`` is false: no events)."""

    def __init__(self, detector: FallDetector | None, log, on_error: Callable[[], None] = lambda: None) -> None:
        self.detector = detector
        self.log = log
        self.failures = 0
        self.bad_gravity = 0
        self._on_error = on_error

    @classmethod
    def from_config(cls, cfg: FallsConfig, robot_id: str, log,
                    on_error: Callable[[], None] = lambda: None) -> FallWatch:
        return cls(FallDetector(cfg, robot_id) if cfg.enabled else None, log, on_error)

    def status(self) -> dict:
        """For the status message: whether detection runs, the camera geometry in use (tilt, roll, floor and
        where each comes from: config, learned or imu), malformed IMU readings and detector failures."""
        if self.detector is None:
            return {"enabled": False}
        geometry = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in self.detector.geometry.items()}
        return {"enabled": True, "geometry": geometry, "bad_gravity": self.bad_gravity, "failures": self.failures}

    def update(self, msg: FitMsg) -> list[FallEvent]:
        """The fall-event messages this frame caused (usually none)."""
        if self.detector is None:
            return []
        cfg = getattr(self.detector, "cfg", None)
        gravity = None
        if cfg is not None and cfg.imu_gravity:
            gravity = getattr(msg.landmarks, "gravity", None)
            if gravity is None:
                gravity = (getattr(msg.landmarks, "extra", None) or {}).get("gravity")
        if gravity is not None:
            try:
                self.detector.set_gravity(_vector3(gravity))
            except (TypeError, ValueError) as exc:   # a bad reading: keep the gravity in use, judge the frame
                self.bad_gravity += 1
                if self.bad_gravity <= LOG_FIRST_FAILURES or self.bad_gravity % LOG_FAILURE_EVERY == 0:
                    self.log.warning("imu_gravity_bad", error=str(exc), seq=msg.result.seq, count=self.bad_gravity)
        try:
            return self.detector.update(msg.result, msg.landmarks.landmarks, msg.image_size, msg.intrinsics)
        except Exception as exc:  # a detector bug must not stop the poses
            self.failures += 1
            self._on_error()
            if self.failures <= LOG_FIRST_FAILURES or self.failures % LOG_FAILURE_EVERY == 0:
                self.log.error("fall_detector_failed", error=repr(exc), seq=msg.result.seq,
                               failures=self.failures)
            return []


def _vector3(value):
    import numpy as np

    g = np.asarray(value, dtype=float)
    if g.shape != (3,):
        raise ValueError(f"frame field gravity must be three numbers (camera axes), got {value!r}")
    return g
