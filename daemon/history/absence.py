"""The person not seen for longer than usual (``hooks.on_absent``, the status's ``presence``): the live side of
:mod:`falls.absence`.

posed watches one room. A person who falls in another room is never seen falling; the only sign is that they
do not come back into view. :class:`PresenceWatch` follows, frame by frame, when the person was last seen and
how long posed has watched since (``absent_s``), and compares that with how long they were out of view at
most on each of the last ``falls.absence_days`` days from the same time of day (:func:`falls.absence.usual_absence`,
learned from the history file's ``watched`` minutes, :mod:`daemon.history.watched`).

* At the start it reads the history file (read-only) once: the end of the last minute that saw the person
  (``person_s >= SEEN_S``) and the watched seconds since, so a restarted daemon goes on with the absence as it
  was (minutes not watched, the daemon off among them, add nothing); but it gives no notice before it has
  watched ``LIVE_FIRST_S`` itself (a person standing in front of the camera at the restart is seen first).
* Each frame (:meth:`add`: its wall time and whether a person was in view, as :class:`HistoryRecorder` counts
  it) adds the time since the frame before, at most ``watched.MAX_FRAME_GAP_S``, as :class:`WatchLog` does; the
  person is SEEN again the moment this minute's seconds with a person in view reach ``SEEN_S``, and from then
  on every frame with them in view is the last time seen (``absent_s`` 0, ``in_view``).
* While the person is out of view (``absent_s`` > 0) their usual for this absence is read from the history, at
  most once a minute (:meth:`tick`), never per frame; once read, it holds until they are seen again. It is also
  read at the start and every ``REFRESH_S`` while they are in view, so that the status says how many days the
  routine is learned from (``days``, ``learning``) before any absence.
* ``absent`` (:class:`AbsenceNotice`, ``POSED_ABSENT=absent``) once ``absent_s`` exceeds the usual plus
  ``falls.absence_margin_h``; ``back`` when the person is seen again after that. Not journalled (like the watch
  notices): a daemon started again judges afresh from the history file.

Nothing of this without the history (``falls.history_enabled`` false) or with ``falls.absence_enabled`` false:
the publisher makes no :class:`PresenceWatch` and the status's ``presence`` is null.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from datetime import tzinfo
from pathlib import Path

from posed.daemon.history.watched import MINUTE_S, WatchLog, frame_seconds
from posed.falls.absence import DAY_S, SEEN_S, Minutes, Usual, usual_absence
from posed.falls.config import FallsConfig

READ_EVERY_S = 60.0     # the usual is read from the history file at most this often
READ_MARGIN_S = 6 * 3600.0  # read this much before the oldest day too: a summer-time hour, sightings just before
REFRESH_S = 600.0       # while the person is in view, the days learned are read again this often (for the status)
# no notice before posed has watched this long since its start: a restarted daemon whose history says the person
# has long been out of view first looks (five times SEEN_S: a person in front of the camera is seen well within it)
LIVE_FIRST_S = 10.0


@dataclass(frozen=True)
class AbsenceNotice:
    """The person not seen for longer than usual (``absent`` True), or seen again after that (False); times in
    unix seconds. ``last_seen_unix``: when the person was last seen before the absence (None: never, as far as
    the history goes); ``absent_s``: the seconds posed watched since then (for ``back``: the whole absence);
    ``usual_s``, ``notice_after_s``: the usual and the threshold it was judged by; ``days``: the past days the
    usual was learned from."""

    absent: bool
    robot: str
    last_seen_unix: float | None
    absent_s: float
    usual_s: float | None
    notice_after_s: float | None
    days: int
    time_unix: float

    @property
    def absence(self) -> str:
        return "absent" if self.absent else "back"

    def to_json(self) -> dict:
        return {"format": "posed.absence", "version": 1, "robot": self.robot, "absence": self.absence,
                "last_seen_unix": _round(self.last_seen_unix, 3), "absent_s": round(self.absent_s, 1),
                "usual_s": _round(self.usual_s, 1), "notice_after_s": _round(self.notice_after_s, 1),
                "days": self.days, "time_unix": round(self.time_unix, 3)}

    def environment(self) -> dict[str, str]:
        seen = "" if self.last_seen_unix is None else repr(round(self.last_seen_unix, 3))
        return {"POSED_ABSENT": self.absence, "POSED_ABSENT_LAST_SEEN_UNIX": seen, "POSED_ROBOT": self.robot}


def _round(x: float | None, digits: int) -> float | None:
    return None if x is None else round(x, digits)


class PresenceWatch:
    """When the person was last seen, how long posed has watched since, and whether that is longer than usual.

    ``path``: the history file (read-only here; the recorder writes it); ``now_unix``: the start (default the
    clock's); ``tz``: the robot's time zone, in which the past days are the same time of day (None: UTC days).
    ``add`` per frame and ``tick`` between frames return an :class:`AbsenceNotice` when the absence notice begins
    or ends, else None; ``state`` is the status's ``presence``."""

    def __init__(self, path: str | os.PathLike, robot: str, cfg: FallsConfig, log, now_unix: float | None = None,
                 read_every_s: float = READ_EVERY_S, tz: tzinfo | None = None) -> None:
        self.path = Path(path)
        self.tz = tz                            # the robot's zone: past days at the same wall-clock time
        self.robot = robot
        self.log = log
        self.days = int(cfg.absence_days)
        self.learn_days = int(cfg.absence_learn_days)
        self.margin_s = float(cfg.absence_margin_h) * 3600.0
        self.read_every_s = read_every_s
        self.t0: float | None = None            # when the person was last seen (None: never)
        self.absent_s = 0.0                     # watched seconds since t0
        self.usual: Usual | None = None         # the latest read; for the current absence when usual.t0 == t0
        self.absent_since: float | None = None  # when the notice was given; None while not absent
        self._last_wall: float | None = None    # the frame before's wall time
        self._minute: float | None = None       # this minute's start ...
        self._minute_person_s = 0.0             # ... its seconds with a person in view
        self._minute_seen = False               # ... and whether they reached SEEN_S
        self._next_read: float | None = None    # monotonic time of the next read of the usual (None: now)
        self._refresh_at: float | None = None   # ... and of the next one while in view (None: now)
        self._in_view = False                   # the last frame had the person in view, seen this minute
        self._live_s = 0.0                      # seconds watched since the start (LIVE_FIRST_S)
        self._failed: str | None = None         # the last read error said
        self._start(time.time() if now_unix is None else now_unix)

    # -- reading the history file ----------------------------------------------------------------------------
    def _history(self) -> WatchLog | None:
        """The history file's watched minutes, opened read-only (the recorder writes them); None without a file."""
        return WatchLog(self.path, readonly=True) if self.path.is_file() else None

    def _start(self, now_unix: float) -> None:
        """The absence so far, from the history: the end of the last minute that saw the person and the watched
        seconds of the minutes since (all of them when it never did)."""
        try:
            history = self._history()
            if history is not None:
                with history:
                    last = history.last_minute_seen(SEEN_S, now_unix)
                    self.t0 = None if last is None else last + MINUTE_S
                    self.absent_s = history.watched_seconds(-math.inf if self.t0 is None else self.t0, now_unix)
        except Exception as exc:        # a record, not an alarm: said, never raised
            self._said_failure("at the start", exc)
        if not math.isfinite(self.absent_s):
            self.absent_s = 0.0

    def _read_usual(self, t0: float) -> None:
        try:
            history = self._history()
            rows = []
            if history is not None:
                with history:
                    rows = history.minutes(t0 - self.days * DAY_S - READ_MARGIN_S, t0) or []
            # (minute, frames, person, fitted, watched_s, person_s): the rule reads the minute and its seconds
            minutes = Minutes.from_rows((r[0], r[4], r[5]) for r in rows)
            self.usual = usual_absence(minutes, t0, self.days, self.learn_days, tz=self.tz)
            self._failed = None
        except Exception as exc:        # a record, not an alarm: said, never raised
            self._said_failure("for the usual", exc)

    def _said_failure(self, when: str, exc: Exception) -> None:
        error = repr(exc)
        if error != self._failed:
            self._failed = error
            self.log.warning("absence_read_failed", error=error, when=when, path=str(self.path),
                             note=f"cannot tell how long the person is usually out of view; tried again every "
                                  f"{self.read_every_s:g} s")

    # -- live ----------------------------------------------------------------------------------------------
    def add(self, wall: float, person: bool) -> AbsenceNotice | None:
        """One frame at unix time ``wall``, with a person in view or not."""
        dt = frame_seconds(self._last_wall, wall)
        self._last_wall = wall
        minute = math.floor(wall / MINUTE_S) * MINUTE_S
        if minute != self._minute:
            self._minute, self._minute_person_s, self._minute_seen = minute, 0.0, False
        self.absent_s += dt
        self._live_s += dt
        if person:
            self._minute_person_s += dt
        self._in_view = False
        if person and (self._minute_seen or self._minute_person_s >= SEEN_S):
            first = not self._minute_seen
            self._minute_seen = self._in_view = True
            notice = self._seen(wall) if first else None
            self.t0, self.absent_s = wall, 0.0          # in view: every frame is the last time seen
            return notice
        return self._judge(wall)

    def tick(self, now: float, now_unix: float) -> AbsenceNotice | None:
        """Between frames (``now`` monotonic, ``now_unix`` the wall time): the usual for this absence read when
        it is missing (at most every ``read_every_s``), and the absence judged with it; at the start and every
        ``REFRESH_S`` also without an absence (the days learned, for the status)."""
        missing = self.t0 is not None and self.absent_s > 0 and not self._usual_now()
        stale = self._refresh_at is None or now >= self._refresh_at
        if (missing or stale) and (self._next_read is None or now >= self._next_read):
            self._next_read, self._refresh_at = now + self.read_every_s, now + REFRESH_S
            self._read_usual(self.t0 if self.t0 is not None else now_unix)
        return self._judge(now_unix)

    def _usual_now(self) -> bool:
        return self.usual is not None and self.usual.t0 == self.t0

    def notice_after_s(self) -> float | None:
        """The watched seconds after which the current absence is longer than usual; None while there is no
        usual for it (learning, never seen, not read yet)."""
        return self.usual.notice_after_s(self.margin_s) if self._usual_now() else None

    def _seen(self, wall: float) -> AbsenceNotice | None:
        notice = None
        if self.absent_since is not None:
            notice = self._notice(False, wall)
            self.absent_since = None
        self.t0, self.absent_s = wall, 0.0
        return notice

    def _judge(self, now_unix: float) -> AbsenceNotice | None:
        if self.absent_since is not None or self._live_s < LIVE_FIRST_S:
            return None
        after = self.notice_after_s()
        if after is None or self.absent_s <= after:
            return None
        self.absent_since = now_unix
        return self._notice(True, now_unix)

    def _notice(self, absent: bool, now_unix: float) -> AbsenceNotice:
        usual = self.usual if self._usual_now() else None
        return AbsenceNotice(absent, self.robot, self.t0, self.absent_s, usual.usual_s if usual else None,
                             self.notice_after_s(), usual.days if usual else 0, now_unix)

    def state(self) -> dict:
        """The status's ``presence``: ``last_seen_unix`` (null: never seen, as far as the history goes),
        ``absent_s`` (watched seconds since), ``usual_s``, ``notice_after_s`` (null while learning or not yet
        read; only for the current absence), ``days`` (past days counted, as last read), ``learn_days``,
        ``learning``, ``absent`` (the notice given, the person not seen since), ``absent_since_unix`` (when the
        notice was given) and ``in_view`` (the latest frame had the person in view, seen this minute)."""
        latest = self.usual
        usual = latest if self._usual_now() else None
        return {"last_seen_unix": _round(self.t0, 3), "absent_s": round(self.absent_s, 1),
                "usual_s": _round(usual.usual_s if usual else None, 1), "notice_after_s": _round(
                    self.notice_after_s(), 1),
                "days": latest.days if latest else 0, "learn_days": self.learn_days,
                "learning": latest is None or latest.learning, "absent": self.absent_since is not None,
                "absent_since_unix": _round(self.absent_since, 3), "in_view": self._in_view}
