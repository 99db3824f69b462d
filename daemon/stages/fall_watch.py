"""Fall detection in the publisher stage: the :mod:`falls` detector run on every fit, in capture order.

Every FitMsg is fed (also frames without a person: the alarm timer runs on the capture timestamps, the one
clock), with its 2D landmarks, image size and camera intrinsics. A detector that raises must not stop the
poses: the frame then yields no event, the stage's error counter goes up and the failure is logged (the
first three, then every hundredth).
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
        self._on_error = on_error

    @classmethod
    def from_config(cls, cfg: FallsConfig, robot_id: str, log,
                    on_error: Callable[[], None] = lambda: None) -> FallWatch:
        return cls(FallDetector(cfg, robot_id) if cfg.enabled else None, log, on_error)

    def update(self, msg: FitMsg) -> list[FallEvent]:
        """The fall-event messages this frame caused (usually none)."""
        if self.detector is None:
            return []
        try:
            return self.detector.update(msg.result, msg.landmarks.landmarks, msg.image_size, msg.intrinsics)
        except Exception as exc:  # a detector bug must not stop the poses
            self.failures += 1
            self._on_error()
            if self.failures <= LOG_FIRST_FAILURES or self.failures % LOG_FAILURE_EVERY == 0:
                self.log.error("fall_detector_failed", error=repr(exc), seq=msg.result.seq,
                               failures=self.failures)
            return []
