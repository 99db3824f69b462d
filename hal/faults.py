"""Fault injection for daemon tests: a wrapper that makes any source drop, stall, disconnect or corrupt.

Configured by the ``source.fault_*`` keys or the URI query (``?drop=0.1&stall_at=20&stall_s=3&disconnect_at=40
&disconnect_s=2&corrupt_at=10&seed=0``). ``N`` below counts the frames the wrapped source delivers since
``open()``, from 0 (for a file read once this is the frame's ``seq``). Each fault fires once per ``open()``.

drop=P           each frame is discarded with probability P (seeded by ``seed``); its seq is missing
stall_at=N       frame N is held back ``stall_s`` seconds: reads meanwhile wait their full timeout and raise
                 SourceTimeout; then frame N is delivered (late: its ``t`` is from before the stall)
disconnect_at=N  frame N is lost and the source is "unplugged" for ``disconnect_s`` seconds (0 = until
                 closed): the first read raises SourceDisconnected at once, later ones after waiting their
                 timeout (or until the camera is back, then they deliver the next frame)
corrupt_at=N     reading frame N raises SourceCorrupt; the next read goes on with frame N+1

With a real-time replay the frames due during a stall or unplug come right after it, back to back.
"""

from __future__ import annotations

import random
import time
from typing import Any

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceDisconnected, SourceTimeout
from posed.hal.frame import Frame
from posed.hal.source import Source


class FaultySource(Source):
    """Wraps ``inner`` and injects the faults of ``config`` (the same config as the inner source's)."""

    def __init__(self, inner: Source, config: SourceConfig | None = None, clock=time.monotonic,
                 sleep=time.sleep) -> None:
        cfg = config or inner.config
        super().__init__(cfg, inner.name)
        self.kind = inner.kind
        self.inner = inner
        self._clock = clock
        self._sleep = sleep
        self.counters.update(fault_dropped=0, fault_stalls=0, fault_disconnects=0, fault_corrupted=0)

    def _open(self) -> None:
        self.inner.open()
        self.state = self.inner.state
        self._n = 0
        self._rng = random.Random(self.config.fault_seed)
        self._held: Frame | None = None
        self._stall_until: float | None = None
        self._unplugged_until: float | None = None

    def _close(self) -> None:
        self.inner.close()

    def _describe(self) -> dict[str, Any]:
        out = self.inner.info
        c = self.config
        out["faults"] = {"drop": c.fault_drop, "stall_at": c.fault_stall_at, "stall_s": c.fault_stall_s,
                         "disconnect_at": c.fault_disconnect_at, "disconnect_s": c.fault_disconnect_s,
                         "corrupt_at": c.fault_corrupt_at, "seed": c.fault_seed}
        out.pop("frames", None)
        if getattr(self, "_unplugged_until", None) is not None:
            out["state"] = "disconnected"
        return out

    def _wait_until(self, until: float, deadline: float) -> bool:
        """Sleep until ``until`` or ``deadline``; True when ``until`` was reached."""
        now = self._clock()
        if now < until:
            self._sleep(max(0.0, min(until, deadline) - now))
        return self._clock() >= until

    def _read(self, timeout_s: float) -> Frame:
        deadline = self._clock() + timeout_s
        c = self.config
        if self._unplugged_until is not None:
            if not self._wait_until(self._unplugged_until, deadline):
                self.state = "disconnected"
                raise SourceDisconnected(f"{self.name}: still unplugged (injected fault disconnect_at="
                                         f"{c.fault_disconnect_at})", self.name)
            self._unplugged_until = None
            self.state = self.inner.state
        if self._stall_until is not None:
            if not self._wait_until(self._stall_until, deadline):
                raise SourceTimeout(f"{self.name}: no frame within {timeout_s:.2f} s (injected fault stall_at="
                                    f"{c.fault_stall_at}, {c.fault_stall_s} s)", self.name)
            self._stall_until = None
            held, self._held = self._held, None
            assert held is not None
            return held
        while True:
            frame = self.inner.read(max(0.0, deadline - self._clock()))
            n = self._n
            self._n += 1
            if n == c.fault_corrupt_at:
                self.count("fault_corrupted")
                raise SourceCorrupt(f"{self.name}: frame {n} (seq {frame.seq}) is corrupt (injected fault "
                                    f"corrupt_at={n})", self.name)
            if n == c.fault_disconnect_at:
                self.count("fault_disconnects")
                self._unplugged_until = (self._clock() + c.fault_disconnect_s) if c.fault_disconnect_s > 0 \
                    else float("inf")
                self.state = "disconnected"
                raise SourceDisconnected(f"{self.name}: unplugged at frame {n} (injected fault disconnect_at={n}, "
                                         f"back after {c.fault_disconnect_s or 'never'} s)", self.name)
            if n == c.fault_stall_at:
                self.count("fault_stalls")
                self._stall_until = self._clock() + c.fault_stall_s
                self._held = frame
                return self._read(max(0.0, deadline - self._clock()))
            if c.fault_drop > 0.0 and self._rng.random() < c.fault_drop:
                self.count("fault_dropped")
                continue
            return frame
