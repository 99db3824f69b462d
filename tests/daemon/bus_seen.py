"""What a real client subscribed to a daemon has received: its fall events and statuses, and a wait for one."""

from __future__ import annotations

import threading
import time


class Seen:
    """The ``on_event`` / ``on_status`` callbacks of :class:`posed.client.PosedClient`, kept under a lock."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.events, self.statuses = [], []

    def event(self, robot, ev):
        with self.lock:
            self.events.append(ev)

    def status(self, robot, st):
        with self.lock:
            self.statuses.append(st)

    def wait(self, what, timeout: float, label: str = "what was awaited"):
        """``what(self)`` once it is truthy (polled under the lock), else an AssertionError after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                found = what(self)
            if found:
                return found
            time.sleep(0.1)
        raise AssertionError(f"timed out after {timeout} s waiting for {label}")
