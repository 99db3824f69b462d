"""Bounded log lines for what outsiders send: :func:`shown` shortens a value they chose, :class:`Throttle`
rate-limits a kind of line.

Rate-limited log lines: at most ``burst`` lines per ``period_s`` for each kind of message, the rest
counted and reported with the next line that is let through (``suppressed``).

For messages an outsider can trigger at will (a flood on the ack key): the log stays readable and bounded
while the counters in the status object still see every one. Times are seconds on the monotonic clock.
"""

from __future__ import annotations

import threading
import time

SHOWN_CHARS = 40


def shown(text: str) -> str:
    """``text`` bounded for a log line: printable, at most SHOWN_CHARS characters (then an ellipsis)."""
    text = "".join(c if c.isprintable() else "?" for c in text[: SHOWN_CHARS + 1])
    return text if len(text) <= SHOWN_CHARS else text[:SHOWN_CHARS] + "…"


class Throttle:
    """``allow(kind)`` -> None (drop this line) or the number of lines of that kind suppressed since the last
    one let through (0 most of the time); thread-safe."""

    def __init__(self, burst: int = 5, period_s: float = 60.0, clock=time.monotonic) -> None:
        self.burst = burst
        self.period_s = period_s
        self._clock = clock
        self._lock = threading.Lock()
        self._windows: dict[str, tuple[float, int, int]] = {}    # kind -> (window start, let through, dropped)

    def allow(self, kind: str) -> int | None:
        now = self._clock()
        with self._lock:
            start, passed, dropped = self._windows.get(kind, (now, 0, 0))
            if now - start >= self.period_s:
                start, passed = now, 0
            if passed >= self.burst:
                self._windows[kind] = (start, passed, dropped + 1)
                return None
            self._windows[kind] = (start, passed + 1, 0)
            return dropped
