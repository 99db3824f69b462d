"""The watchdog's decisions, kept free of processes so they can be tested on their own.

* :func:`verdict` looks at a stage's health row: ``dead`` (the process exited), ``stuck`` (busy on one step
  longer than ``stuck_after_s``, warming up longer than ``startup_timeout_s``, or no heartbeat for
  ``stuck_after_s`` while idle — e.g. SIGSTOP), else ``ok``.
* :class:`RestartPolicy` gives the backoff before a restart (0 s for the first restart of a stage within the
  window, then 0.5 s doubling up to ``backoff_max_s``) and says when to escalate: more than
  ``max_restarts`` restarts of any stages within ``window_s``. Escalation means the supervisor stops sending
  WATCHDOG=1 so systemd restarts the whole unit (or exits with 70 when no systemd watchdog is active).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class Verdict:
    kind: str           # ok | dead | stuck
    reason: str = ""


def verdict(alive: bool, exitcode: int | None, state: str, beat: float, step_started: float,
            started: float, now: float, stuck_after_s: float, startup_timeout_s: float) -> Verdict:
    """Judge one stage from its process and its health row (times on the monotonic clock)."""
    if not alive:
        return Verdict("dead", f"process exited with code {exitcode}")
    if state == "starting":
        if now - started > startup_timeout_s:
            return Verdict("stuck", f"still warming up after {now - started:.1f} s "
                                    f"(pipeline.startup_timeout_s = {startup_timeout_s:g})")
        return Verdict("ok")
    if state in ("stopping", "stopped", "fatal", "failed"):
        return Verdict("ok")
    if not math.isnan(step_started) and now - step_started > stuck_after_s:
        return Verdict("stuck", f"busy on one step for {now - step_started:.1f} s "
                                f"(pipeline.stuck_after_s = {stuck_after_s:g})")
    if now - beat > stuck_after_s:
        return Verdict("stuck", f"no heartbeat for {now - beat:.1f} s (pipeline.stuck_after_s = {stuck_after_s:g})")
    return Verdict("ok")


class RestartPolicy:
    """Backoff per stage and escalation over all stages, on a sliding window."""

    def __init__(self, max_restarts: int, window_s: float, backoff_base_s: float = 0.5,
                 backoff_max_s: float = 10.0) -> None:
        self.max_restarts = max_restarts
        self.window_s = window_s
        self.backoff_base_s = backoff_base_s
        self.backoff_max_s = backoff_max_s
        self._all: deque[float] = deque()
        self._per_stage: dict[str, deque[float]] = {}
        self.total = 0

    def _trim(self, q: deque[float], now: float) -> None:
        while q and q[0] < now - self.window_s:
            q.popleft()

    def delay(self, stage: str, now: float) -> float:
        """Seconds to wait before restarting ``stage`` now."""
        q = self._per_stage.setdefault(stage, deque())
        self._trim(q, now)
        if not q:
            return 0.0
        return min(self.backoff_max_s, self.backoff_base_s * 2 ** (len(q) - 1))

    def record(self, stage: str, now: float) -> None:
        """A restart of ``stage`` happened at ``now``."""
        self._per_stage.setdefault(stage, deque()).append(now)
        self._all.append(now)
        self.total += 1

    def recent(self, now: float) -> int:
        self._trim(self._all, now)
        return len(self._all)

    def escalated(self, now: float) -> bool:
        return self.recent(now) > self.max_restarts
