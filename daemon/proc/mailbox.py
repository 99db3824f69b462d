"""Latest-value mailboxes in shared memory: how the stage processes pass small frozen dataclasses.

A mailbox holds one pickled message. ``put`` replaces whatever is there, so a slow reader never makes a
queue build up: the newest message wins and the one it replaced counts as a drop. A reader ``wait``s on a
semaphore "doorbell" rung by ``put``. Unlike ``multiprocessing.Queue`` nothing here holds a lock that a
process killed with SIGKILL could leave taken, so the watchdog can kill and restart either end at any time:

    header  4 int64  [lock (odd while writing), written id, consumed id, length]
    data    capacity bytes

The writer makes ``lock`` odd (``|= 1``: a writer killed mid-write leaves it odd, and the next write must still
end even), writes data and ids, and bumps it to even; a reader copies the bytes and keeps them only when
``lock`` was even and unchanged (one writer and one reader per mailbox; x86-64 ordering).
"""

from __future__ import annotations

import pickle
import threading
import time
from typing import Any

import numpy as np

_HDR = 4 * 8


class Mailbox:
    """One mailbox over ``buf[offset : offset + 32 + capacity]``; ``doorbell`` is a multiprocessing Semaphore
    (or None for a mailbox that is only polled)."""

    def __init__(self, name: str, buf, offset: int, capacity: int, doorbell=None) -> None:
        self.name = name
        self.capacity = capacity
        self._hdr = np.ndarray((4,), np.int64, buf, offset)
        self._data = np.ndarray((capacity,), np.uint8, buf, offset + _HDR)
        self._doorbell = doorbell
        self._wlock = threading.Lock()  # threads of one writer process take turns

    @staticmethod
    def size(capacity: int) -> int:
        return _HDR + capacity

    def put(self, message: Any) -> bool:
        """Publish ``message``; True when it replaced one the reader had not taken (a drop)."""
        blob = pickle.dumps(message, protocol=5)
        if len(blob) > self.capacity:
            raise ValueError(f"a {type(message).__name__} of {len(blob)} bytes does not fit mailbox "
                             f"{self.name!r} ({self.capacity} bytes)")
        with self._wlock:
            hdr = self._hdr
            dropped = int(hdr[1]) > int(hdr[2])
            hdr[0] |= 1
            self._data[: len(blob)] = np.frombuffer(blob, np.uint8)
            hdr[3] = len(blob)
            hdr[1] += 1
            hdr[0] += 1
        bell = self._doorbell
        if bell is not None:
            try:
                if bell.get_value() == 0:
                    bell.release()
            except (OSError, ValueError):
                pass
        return dropped

    def pending(self) -> bool:
        """True while a message waits that the reader has not taken."""
        return int(self._hdr[1]) > int(self._hdr[2])

    def take(self) -> Any | None:
        """The waiting message (marking it taken), or None."""
        hdr = self._hdr
        for _ in range(100):
            lock = int(hdr[0])
            written = int(hdr[1])
            if written <= int(hdr[2]):
                return None
            if lock % 2:
                continue
            n = int(hdr[3])
            blob = self._data[:n].tobytes()
            if int(hdr[0]) != lock:
                continue
            hdr[2] = written
            return pickle.loads(blob)
        return None

    def wait(self, timeout: float) -> Any | None:
        """The next message, waiting up to ``timeout`` seconds for one; None if none came."""
        message = self.take()
        if message is not None:
            return message
        if self._doorbell is None:
            return None
        deadline = time.monotonic() + timeout
        while True:                      # a stale ring (message taken without waiting) wakes us early
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self._doorbell.acquire(timeout=left)
            message = self.take()
            if message is not None:
                return message

    def detach(self) -> None:
        self._hdr = self._data = None
