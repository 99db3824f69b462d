"""The publisher's side of the joint-angle history: one ``add`` per fit and the store's maintenance about
once a minute (:mod:`daemon.history.store` keeps, downsamples and deletes the rows); every frame also counts in
the minutes posed watched (:mod:`daemon.history.watched`), written at the same time, and in the person's
presence (:mod:`daemon.history.absence`: not seen for longer than usual), whose notices :meth:`notices` hands
on.

The row's wall time is the capture timestamp converted to unix seconds; the schedule runs on the monotonic
clock. With ``falls.history_enabled`` false there is no store and every call does nothing.
"""

from __future__ import annotations

from posed.daemon import clock
from posed.daemon.history.absence import AbsenceNotice, PresenceWatch
from posed.daemon.history.store import AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.fitting import FitResult

MAINTAIN_EVERY_S = 60.0


class HistoryRecorder:
    """Feeds an :class:`AngleHistory` (or nothing, when ``store`` is None)."""

    def __init__(self, store: AngleHistory | None, log, maintain_every_s: float = MAINTAIN_EVERY_S,
                 now: float | None = None, presence: PresenceWatch | None = None) -> None:
        self.store = store
        self.log = log
        self.presence = presence if store is not None else None    # fed the frames the history counts
        self._notices: list[AbsenceNotice] = []
        self.maintain_every_s = maintain_every_s
        self._next_maintain = (clock.now() if now is None else now) + maintain_every_s
        # the watched minutes are written as often as the angle rows (falls.history_commit_every_s): a report
        # made a few seconds after the start must not show samples of a day it says posed did not watch
        self.watch_flush_every_s = float(getattr(getattr(store, "cfg", None), "history_commit_every_s", 5.0))
        self._next_watch_flush = (clock.now() if now is None else now) + self.watch_flush_every_s
        self.watched: WatchLog | None = None      # the minutes posed watched, in the same file
        path = getattr(store, "path", None)
        if path is not None:
            try:
                self.watched = WatchLog(path, log)
            except Exception as exc:   # the angles go on without it; the report then says it cannot tell
                log.error("watched_unavailable", error=repr(exc), path=str(path))

    def add(self, result: FitResult, t_capture: float) -> None:
        """Offer one fit (``t_capture``: its capture timestamp, monotonic seconds) to the store, which keeps
        it if the rate allows, and count the frame in its minute (watched: a person in view or not)."""
        if self.store is not None:
            wall = clock.wall_from_monotonic(t_capture)
            self.store.add(result, wall)
            person = result.ok or result.reason != "no person"
            if self.watched is not None:
                self.watched.add(wall, person=person, fitted=result.ok)
            if self.presence is not None:
                self._keep(self.presence.add(wall, person))

    def _keep(self, notice: AbsenceNotice | None) -> None:
        if notice is not None:
            self._notices.append(notice)

    def notices(self) -> list[AbsenceNotice]:
        """The absence notices since the last call (:class:`PresenceWatch`), oldest first."""
        out, self._notices = self._notices, []
        return out

    def tick(self, now: float) -> None:
        """Write the watched minutes every ``watch_flush_every_s``; downsample and expire old rows every
        ``maintain_every_s``; a failure is logged, never raised. The presence reads the person's usual absence
        when it needs it (at most once a minute)."""
        if self.presence is not None:
            self._keep(self.presence.tick(now, clock.wall_from_monotonic(now)))
        if self.watched is not None and now >= self._next_watch_flush:
            self._next_watch_flush = now + self.watch_flush_every_s
            self.watched.flush()
        if now < self._next_maintain:
            return
        self._next_maintain = now + self.maintain_every_s
        if self.store is None:
            return
        try:
            self.store.maintain()
        except Exception as exc:
            self.log.error("history_maintenance_failed", error=repr(exc))
        if self.watched is not None:
            self.watched.flush()
            days = getattr(getattr(self.store, "cfg", None), "history_retention_days", None)
            if days is not None:
                self.watched.expire(clock.wall_from_monotonic(now) - days * 86400.0)

    def close(self) -> None:
        """Write the buffered rows and close the store."""
        if self.watched is not None:
            self.watched.close()
        if self.store is not None:
            self.store.close()
