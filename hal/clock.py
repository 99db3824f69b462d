"""Mapping a camera's own clock onto the daemon's one clock, ``time.monotonic()`` (seconds).

A frame's device timestamp ``d`` and its arrival time ``a`` (monotonic) differ by a fixed clock offset plus a
variable transport delay >= 0. The smallest ``a - d`` over a sliding window is the best estimate of the offset
(the frame that came through fastest); ``d + offset`` is then the capture time on the monotonic clock, free of
the delay jitter. The window lets the estimate follow the slow drift between the two clocks; a jump larger
than ``jump_s`` (the device clock restarted) starts a new estimate.
"""

from __future__ import annotations

import math
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


# A step longer than this between two consecutive frames of a replay is taken for a clock jump, not a gap.
MAX_STEP_S = 60.0


class ReplayClock:
    """The capture clock of a replay (videos, image folders, RealSense playback and, in the daemon, landmark
    recordings; paced or not): the recording's time line, step by step, never going back and never leaping.

    A frame's step from the frame before is the recorded one when it is in (0, ``max_step_s``]. Any other
    step — a repeated timestamp, a clock that went back (an NTP correction, a camera reset), a jump of more
    than ``max_step_s`` forward — is a clock jump: the frame comes ``period_s`` after the one before, and the
    time line goes on from it (the frames after keep their recorded steps). ``jumps`` counts them.
    """

    def __init__(self, max_step_s: float = MAX_STEP_S) -> None:
        self.max_step_s = float(max_step_s)
        self.shift = 0.0                  # seconds added to the recorded time line since the first jump
        self.last: float | None = None    # the last time handed out
        self.jumps = 0
        self.last_jump_s = 0.0            # the recorded step of the last jump (negative: backwards)

    def map(self, t: float, period_s: float) -> float:
        """The capture time of a frame recorded at ``t`` (seconds, the caller's time line), ``period_s`` the
        source's frame period."""
        if not math.isfinite(t):                         # not a time at all: one period on, shift kept
            if self.last is None:
                raise ValueError(f"the first timestamp of a replay must be a number, got {t!r}")
            self.jumps += 1
            self.last_jump_s = 0.0
            self.last += period_s
            return self.last
        out = t + self.shift
        if self.last is not None:
            step = out - self.last
            if not (0.0 < step <= self.max_step_s):
                self.jumps += 1
                self.last_jump_s = step
                out = self.last + period_s
                self.shift = out - t
        self.last = out
        return out
