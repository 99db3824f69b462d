"""The publisher's side of the joint-angle history: one ``add`` per fit and the store's maintenance about
once a minute (:mod:`daemon.history.store` keeps, downsamples and deletes the rows).

The row's wall time is the capture timestamp converted to unix seconds; the schedule runs on the monotonic
clock. With ``falls.history_enabled`` false there is no store and every call does nothing.
"""

from __future__ import annotations

from posed.daemon import clock
from posed.daemon.history.store import AngleHistory
from posed.fitting import FitResult

MAINTAIN_EVERY_S = 60.0


class HistoryRecorder:
    """Feeds an :class:`AngleHistory` (or nothing, when ``store`` is None)."""

    def __init__(self, store: AngleHistory | None, log, maintain_every_s: float = MAINTAIN_EVERY_S,
                 now: float | None = None) -> None:
        self.store = store
        self.log = log
        self.maintain_every_s = maintain_every_s
        self._next_maintain = (clock.now() if now is None else now) + maintain_every_s

    def add(self, result: FitResult, t_capture: float) -> None:
        """Offer one fit (``t_capture``: its capture timestamp, monotonic seconds) to the store, which keeps
        it if the rate allows."""
        if self.store is not None:
            self.store.add(result, clock.wall_from_monotonic(t_capture))

    def tick(self, now: float) -> None:
        """Downsample and expire old rows every ``maintain_every_s``; a failure is logged, never raised."""
        if now < self._next_maintain:
            return
        self._next_maintain = now + self.maintain_every_s
        if self.store is None:
            return
        try:
            self.store.maintain()
        except Exception as exc:
            self.log.error("history_maintenance_failed", error=repr(exc))

    def close(self) -> None:
        """Write the buffered rows and close the store."""
        if self.store is not None:
            self.store.close()
