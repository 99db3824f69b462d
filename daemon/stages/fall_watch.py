"""Fall detection in the publisher stage: the :mod:`falls` detector run on every fit, in capture order.

Every FitMsg is fed (also frames without a person: the alarm timer runs on the capture timestamps, the one
clock), with its 2D landmarks, image size and camera intrinsics. A detector that raises must not stop the
poses: the frame then yields no event, the stage's error counter goes up and the failure is logged (the
first three, then every hundredth).

IMU gravity: a frame whose landmark frame carries ``gravity`` (three numbers, the accelerometer's down
vector in the colour camera's axes, any length; a ``*.landmarks.jsonl`` line's extra field ``"gravity"``)
sets the detector's gravity when ``falls.imu_gravity`` is on. No capture source fills it yet (the RealSense
motion stream is not read); recordings can carry it.
"""

from __future__ import annotations

from collections.abc import Callable

from daemon.messages import FitMsg
from falls import FallDetector, FallEvent, FallsConfig

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

    def update(self, msg: FitMsg) -> list[FallEvent]:
        """The fall-event messages this frame caused (usually none)."""
        if self.detector is None:
            return []
        cfg = getattr(self.detector, "cfg", None)
        extra = getattr(msg.landmarks, "extra", None) or {}
        gravity = extra.get("gravity") if cfg is not None and cfg.imu_gravity else None
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
