"""The health board: one row of float64 per stage in shared memory, written by the stage, read by the watchdog.

A stage writes its heartbeat, when its current step began (NaN when idle), counters and latency percentiles
straight into its row: no messages, nothing a killed or stopped process could block. The supervisor writes
only ``stop`` (a request to finish) and ``go`` (every stage is ready: the capture stage may start reading),
and reads rows as :class:`daemon.messages.StageHealth`.
"""

from __future__ import annotations

import math

import numpy as np

from posed.daemon.messages import StageHealth

FIELDS = (
    "pid", "beat", "step_started", "frames", "drops", "state", "ready", "stop", "fps",
    "step_p50_ms", "step_p95_ms", "step_max_ms", "lat_p50_ms", "lat_p95_ms", "lat_max_ms",
    "camera", "skipped", "errors", "started", "go", "bad_frames",
    "unstored", "storage_fault",      # publisher: fall-event messages not on disk; 1 while the state dir fails
    "bus_down",                       # web: 1 while it cannot reach the bus
)
F = {name: i for i, name in enumerate(FIELDS)}

STATES = ("starting", "running", "stopping", "stopped", "fatal", "failed")
CAMERA_STATES = ("none", "opening", "open", "lost", "ended", "error", "paused")   # paused: for privacy


class HealthBoard:
    """Rows of :data:`FIELDS` for ``stages`` over a shared buffer."""

    def __init__(self, stages: tuple[str, ...], buf, offset: int) -> None:
        self.stages = stages
        self._rows = np.ndarray((len(stages), len(FIELDS)), np.float64, buf, offset)

    @staticmethod
    def size(n_stages: int) -> int:
        return n_stages * len(FIELDS) * 8

    def row(self, stage: str) -> HealthRow:
        return HealthRow(self._rows[self.stages.index(stage)])

    def reset(self, stage: str, now: float) -> None:
        """Before (re)starting a stage: a fresh row whose startup counts as one step begun ``now``."""
        r = self._rows[self.stages.index(stage)]
        r[:] = 0.0
        r[F["step_started"]] = now
        r[F["beat"]] = now
        r[F["started"]] = now
        for k in ("fps", "step_p50_ms", "step_p95_ms", "step_max_ms", "lat_p50_ms", "lat_p95_ms", "lat_max_ms"):
            r[F[k]] = math.nan

    def health(self, stage: str) -> StageHealth:
        r = self.row(stage)
        step = r.get("step_started")
        return StageHealth(stage=stage, pid=int(r.get("pid")), beat=r.get("beat"),
                           step_started=None if math.isnan(step) else step, frames=int(r.get("frames")),
                           drops=int(r.get("drops")), state=STATES[int(r.get("state"))])

    def detach(self) -> None:
        self._rows = None


class HealthRow:
    """One stage's row."""

    __slots__ = ("_r",)

    def __init__(self, r: np.ndarray) -> None:
        self._r = r

    def get(self, field: str) -> float:
        return float(self._r[F[field]])

    def set(self, field: str, value: float) -> None:
        self._r[F[field]] = value

    def add(self, field: str, value: float = 1.0) -> None:
        self._r[F[field]] += value

    @property
    def state(self) -> str:
        return STATES[int(self._r[F["state"]])]

    def set_state(self, state: str) -> None:
        self._r[F["state"]] = STATES.index(state)

    @property
    def camera(self) -> str:
        return CAMERA_STATES[int(self._r[F["camera"]])]

    def set_camera(self, state: str) -> None:
        self._r[F["camera"]] = CAMERA_STATES.index(state)

    def snapshot(self) -> dict[str, float]:
        return {name: float(self._r[i]) for i, name in enumerate(FIELDS)}
