"""Rolling statistics for the status topic: percentiles over the last samples and a frame-rate meter."""

from __future__ import annotations

import math
from collections import deque

import numpy as np


class Window:
    """The last ``size`` samples; percentiles in the sample unit (NaN when empty)."""

    def __init__(self, size: int = 256) -> None:
        self._values: deque[float] = deque(maxlen=size)

    def add(self, value: float) -> None:
        self._values.append(value)

    def __len__(self) -> int:
        return len(self._values)

    def percentiles(self) -> tuple[float, float, float]:
        """(p50, p95, max)."""
        if not self._values:
            return math.nan, math.nan, math.nan
        arr = np.fromiter(self._values, np.float64, len(self._values))
        p50, p95 = np.percentile(arr, (50, 95))
        return float(p50), float(p95), float(arr.max())


class RateMeter:
    """Events per second over the last ``horizon_s`` seconds of the given clock."""

    def __init__(self, horizon_s: float = 2.0) -> None:
        self.horizon_s = horizon_s
        self._times: deque[float] = deque()

    def tick(self, t: float) -> None:
        self._times.append(t)
        self._trim(t)

    def rate(self, now: float) -> float:
        self._trim(now)
        if not self._times:
            return 0.0
        span = max(now - self._times[0], 1e-9)
        if len(self._times) < 2:
            return 1.0 / self.horizon_s
        return (len(self._times) - 1) / span if span > 0.5 * self.horizon_s else len(self._times) / self.horizon_s

    def _trim(self, now: float) -> None:
        while self._times and self._times[0] < now - self.horizon_s:
            self._times.popleft()


def percentile_summary(values, nd: int = 1) -> dict:
    """{"p50", "p95", "max", "n"} of a list of numbers (None when empty)."""
    if not len(values):
        return {"p50": None, "p95": None, "max": None, "n": 0}
    arr = np.asarray(values, np.float64)
    p50, p95 = np.percentile(arr, (50, 95))
    return {"p50": round(float(p50), nd), "p95": round(float(p95), nd), "max": round(float(arr.max()), nd),
            "n": int(arr.size)}
