"""Mapping a camera's own clock onto the daemon's one clock, ``time.monotonic()`` (seconds).

A frame's device timestamp ``d`` and its arrival time ``a`` (monotonic) differ by a fixed clock offset plus a
variable transport delay >= 0. The smallest ``a - d`` over a sliding window is the best estimate of the offset
(the frame that came through fastest); ``d + offset`` is then the capture time on the monotonic clock, free of
the delay jitter. The window lets the estimate follow the slow drift between the two clocks; a jump larger
than ``jump_s`` (the device clock restarted) starts a new estimate.
"""

from __future__ import annotations

import time
from collections import deque


class DeviceClock:
    """Device seconds -> monotonic seconds, by the running minimum of (arrival - device)."""

    def __init__(self, window: int = 300, jump_s: float = 1.0) -> None:
        if window < 1:
            raise ValueError("window must be >= 1")
        self.window = window
        self.jump_s = jump_s
        self._deltas: deque[float] = deque(maxlen=window)
        self.offset: float | None = None
        self.resets = 0

    def map(self, device_s: float, arrival_s: float) -> float:
        """Monotonic capture time of a frame stamped ``device_s`` that arrived at ``arrival_s``."""
        delta = arrival_s - device_s
        if self.offset is not None and abs(delta - self.offset) > self.jump_s:
            self._deltas.clear()
            self.resets += 1
        self._deltas.append(delta)
        self.offset = min(self._deltas)
        return min(device_s + self.offset, arrival_s)


def wall_to_monotonic(unix_s: float) -> float:
    """Monotonic seconds of a Unix time taken on this machine (for timestamps on the host's system clock)."""
    return unix_s - (time.time() - time.monotonic())


def wait_until_due(t_due: float, deadline: float, timeout_s: float, name: str, clock, sleep) -> None:
    """Real-time replay: sleep until a frame's capture time ``t_due`` (seconds, monotonic clock), but never
    past the read's ``deadline``; raise SourceTimeout when the frame is due after the read timeout."""
    from posed.hal.errors import SourceTimeout

    wait = t_due - clock()
    if wait <= 0:
        return
    sleep(min(wait, max(0.0, deadline - clock())))
    if clock() < t_due - 1e-4:
        raise SourceTimeout(f"{name}: the next frame is due in {t_due - clock():.2f} s, "
                            f"after the {timeout_s:.2f} s read timeout (a gap in the recording)", name)
