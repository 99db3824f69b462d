"""The interface every source implements: ``open()``, ``read(timeout_s) -> Frame``, ``close()``, ``info``.

A source is created closed (``hal.open_source`` does not open it); ``with source:`` opens and closes it.
``info["state"]`` is one of closed, streaming, reconnecting, disconnected, ended.
``read`` never waits longer than its timeout (default ``source.read_timeout_s``): it returns a frame or
raises a :class:`hal.errors.SourceError`.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import Any

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceError, SourceTimeout
from posed.hal.frame import Frame


class Source(abc.ABC):
    """A camera or recording. Subclasses implement ``_open``, ``_read``, ``_close`` and ``_describe``."""

    kind = "source"

    def __init__(self, config: SourceConfig, name: str) -> None:
        self.config = config
        self.name = name
        self._is_open = False
        self.state = "closed"
        self.counters: dict[str, int] = {"frames": 0}
        # the largest frame (width x height) the reader takes; None: any. Replays of image files check it on
        # the file's header, before decoding (a 10000x10000 image is skipped as SourceCorrupt, not decoded)
        self.max_pixels: int | None = None
        self._consecutive_timeouts = 0  # reads in a row that got no frame (cameras; see _timed_out)

    # -- public API ---------------------------------------------------------------------------------------
    @property
    def info(self) -> dict[str, Any]:
        """What this source is and how it is doing: kind, name, state, size, counters (a fresh dict)."""
        out: dict[str, Any] = {"kind": self.kind, "name": self.name, "state": self.state}
        out.update(self._describe())
        out.update(self.counters)
        return out

    @property
    def is_open(self) -> bool:
        return self._is_open

    def open(self) -> Source:
        """Open the camera or file; raises SourceNotFound, SourceUnsupported, SourceCorrupt. Idempotent."""
        if not self._is_open:
            self._open()
            self._is_open = True
            if self.state == "closed":
                self.state = "streaming"
        return self

    def read(self, timeout_s: float | None = None) -> Frame:
        """The next frame, waiting at most ``timeout_s`` (default ``source.read_timeout_s``)."""
        if not self._is_open:
            raise SourceError(f"{self.name}: read() on a source that is not open; call open() first or use "
                              "`with hal.open_source(...) as src:`", self.name)
        timeout = self.config.read_timeout_s if timeout_s is None else max(0.0, float(timeout_s))
        frame = self._read(timeout)
        self.counters["frames"] += 1
        return frame

    def close(self) -> None:
        """Release the camera or file. Idempotent; never raises."""
        if self._is_open:
            self._is_open = False
            try:
                self._close()
            finally:
                self.state = "closed"

    def __enter__(self) -> Source:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} {self.state}>"

    # -- for subclasses -----------------------------------------------------------------------------------
    def count(self, key: str, n: int = 1) -> None:
        self.counters[key] = self.counters.get(key, 0) + n

    def _timed_out(self, timeout_s: float, reopen: Callable[[], None]) -> SourceTimeout:
        """Count a read that got no frame within ``timeout_s`` seconds (counter ``timeouts``); after
        ``source.timeouts_before_reopen`` of them in a row call ``reopen()``. Returns the error to raise."""
        self._consecutive_timeouts += 1
        self.count("timeouts")
        n, limit = self._consecutive_timeouts, self.config.timeouts_before_reopen
        if n >= limit:
            reopen()
            return SourceTimeout(f"{self.name}: no frame within {timeout_s:.2f} s, {n} times in a row; re-opening "
                                 "the camera", self.name)
        return SourceTimeout(f"{self.name}: no frame within {timeout_s:.2f} s ({n} in a row; re-open after "
                             f"{limit})", self.name)

    @abc.abstractmethod
    def _open(self) -> None: ...

    @abc.abstractmethod
    def _read(self, timeout_s: float) -> Frame: ...

    @abc.abstractmethod
    def _close(self) -> None: ...

    def _describe(self) -> dict[str, Any]:
        return {}
