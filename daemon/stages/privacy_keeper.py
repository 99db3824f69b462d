"""The pause for privacy, kept by the publisher stage (docs/daemon.md, "Pausing for privacy").

The person at home asks the robot's software (a voice UI, an app, a button) to stop watching for a while; it
queries ``posed/ROBOT/privacy/pause?for=15m;by=voice`` (:mod:`daemon.bus.pause_query`). :class:`PrivacyKeeper`

* answers it (:meth:`ask`, on a Zenoh thread): a new pause, or one replacing the running pause (shorter or
  longer; its start is kept), clamped to ``privacy.max_pause_s``; ``for=0`` resumes now (always allowed). It
  refuses a pause when ``privacy.allow_pause`` is false, or while a fall event is open and not acknowledged (a
  person who may be on the floor is never left unwatched): :class:`PauseRefused` with the error and the fix;
* keeps it in the state directory (``privacy.json``, written atomically: :mod:`daemon.stages.privacy_file`) so a
  daemon restarted during a pause stays paused until it ends; an expired or unreadable file is ignored (said in
  the log);
* hands it to the capture stage (the ``privacy`` mailbox: :class:`daemon.stages.privacy_gate.PrivacyOrder`) at
  each change and every ``REFORWARD_S`` (a restarted capture stage has none);
* ends it when its time has come (:meth:`tick`, the publisher's loop) and records every pause in the history
  file (``PauseLog``: table ``paused``);
* says it in the status (:meth:`status`: the ``privacy`` field) and in the reply (:meth:`message`,
  ``posed.privacy`` v1).

Times: unix seconds (the wall clock: a pause ends at a time of day, also across a restart). The monotonic clock
(the publisher's loop passes its ``now``) schedules the re-forwarding and bounds every pause: it ends once as many
seconds have passed as it was given when asked (or had left when restored), whatever the wall clock does meanwhile
(NTP stepping a clock that was a day ahead must not leave the person unwatched for a day). Logged: ``privacy_pause_started``,
``privacy_pause_changed``, ``privacy_pause_ended``, ``privacy_pause_refused``, ``privacy_pause_restored``,
``privacy_file_ignored``, ``privacy_file_not_saved``; never per frame.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

from posed.daemon import clock
from posed.daemon.bus.pause_query import PauseRefused, PauseRequest
from posed.daemon.config.sections import PrivacyConfig
from posed.daemon.stages.privacy_file import (
    EndedPause,
    Pause,
    PrivacyFileError,
    privacy_path,
    read_privacy_file,
    write_privacy_file,
)
from posed.daemon.stages.privacy_gate import REFORWARD_S, PrivacyOrder


class PrivacyKeeper:
    """The running pause (``pause``, None while watching) and the last ended one (``last``); thread-safe.

    ``mailbox``: the ``privacy`` mailbox to the capture stage (None: nowhere); ``pause_log``: a ``PauseLog`` of the
    history file (``begin``/``end``/``close``; None: not recorded); ``open_fall()``: the id of a fall event that
    is open and not acknowledged, or None; ``wall``: the unix clock."""

    def __init__(self, cfg: PrivacyConfig, robot: str, state_dir: Path, log, *, mailbox=None, pause_log=None,
                 open_fall: Callable[[], str | None] = lambda: None, wall: Callable[[], float] = time.time,
                 mono: Callable[[], float] = clock.now) -> None:
        self.cfg = cfg
        self.robot = robot
        self.path = privacy_path(state_dir)
        self.log = log
        self._mailbox = mailbox
        self._pause_log = pause_log
        self._open_fall = open_fall
        self._wall = wall
        self._mono = mono
        self._deadline_mono = float("inf")   # the running pause ends by then on the monotonic clock too
        self._lock = threading.Lock()
        self.pause: Pause | None = None
        self.last: EndedPause | None = None
        self.clamped = False                 # the running pause was cut to max_pause_s
        self.save_error: str | None = None   # privacy.json could not be written (the pause holds in memory)
        self._log_since: float | None = None     # since_unix of the PauseLog's open row (the pause's)
        self._next_forward = 0.0
        self._mailbox_error: str | None = None
        self._restore()
        self._forward()

    # ------------------------------------------------------------------ state
    @property
    def paused(self) -> bool:
        return self.pause is not None

    def _restore(self) -> None:
        now = self._wall()
        try:
            pause, last = read_privacy_file(self.path)
        except PrivacyFileError as exc:
            self.log.warning("privacy_file_ignored", file=str(self.path), error=str(exc),
                             note="no pause is kept from it: posed watches",
                             fix="nothing to do; the file is written again at the next pause")
            return
        self.last = last
        if pause is None:
            return
        if pause.until_unix <= now:
            self.log.info("privacy_file_ignored", file=str(self.path), reason="the pause in it has ended",
                          until_unix=round(pause.until_unix, 3), by=pause.by)
            self.last = EndedPause(pause.since_unix, pause.until_unix, pause.by, "time")
            self._save()
            return
        if not self.cfg.allow_pause:
            self.log.warning("privacy_file_ignored", file=str(self.path), until_unix=round(pause.until_unix, 3),
                             reason="privacy.allow_pause is false now: the pause is not kept, posed watches")
            self.last = EndedPause(pause.since_unix, now, pause.by, "stopped")
            self._save()
            return
        until = min(pause.until_unix, now + self.cfg.max_pause_s)
        self.pause = Pause(pause.since_unix, until, pause.by)
        self._deadline_mono = self._mono() + (until - now)
        self.log.info("privacy_pause_restored", since_unix=round(pause.since_unix, 3), until_unix=round(until, 3),
                      by=pause.by, remaining_s=round(until - now, 1),
                      note="started again during a pause for privacy: paused until it ends")
        self._log_begin(pause.since_unix, until, pause.by)   # the same row again (PauseLog reopens it)

    # ------------------------------------------------------------------ the query (a Zenoh thread)
    def ask(self, request: PauseRequest) -> dict:
        """Answer one query: the ``posed.privacy`` message after it; raises :class:`PauseRefused`."""
        with self._lock:
            now = self._wall()
            if request.resume:
                self._end(now, "resumed", request.by)
                return self._message(now, clamped=False)
            if not self.cfg.allow_pause:
                self._refuse("pausing is not allowed on this robot (privacy.allow_pause is false)",
                             "ask the robot's administrator to set privacy.allow_pause: true in posed's config",
                             request)
            fall = self._open_fall()
            if fall is not None:
                self._refuse(f"fall event {fall} is open and not acknowledged: a person who may be on the floor "
                             "cannot be left unwatched",
                             f"acknowledge fall {fall} first (posed events ack {fall}), then ask again", request)
            for_s = min(request.for_s, self.cfg.max_pause_s)
            clamped = request.for_s > self.cfg.max_pause_s
            running = self.pause
            since = running.since_unix if running is not None else now
            by = request.by if request.by is not None or running is None else running.by
            self.pause = Pause(since, now + for_s, by)
            self._deadline_mono = self._mono() + for_s
            self.clamped = clamped
            self._save()
            if running is None:
                self.log.info("privacy_pause_started", since_unix=round(now, 3), until_unix=round(now + for_s, 3),
                              for_s=round(for_s, 1), by=by, clamped=clamped, asked_s=round(request.for_s, 1))
                self._log_begin(now, now + for_s, by)
            else:
                self.log.info("privacy_pause_changed", since_unix=round(since, 3), until_unix=round(now + for_s, 3),
                              was_until_unix=round(running.until_unix, 3), by=by, clamped=clamped)
                self._log_begin(since, now + for_s, by)
            self._forward()
            return self._message(now, clamped)

    def _refuse(self, error: str, fix: str, request: PauseRequest) -> None:
        self.log.warning("privacy_pause_refused", error=error, fix=fix, by=request.by,
                         asked_s=round(request.for_s, 1))
        raise PauseRefused(error, fix)

    # ------------------------------------------------------------------ the publisher's loop
    def tick(self, now: float) -> None:
        """End a pause whose time has come (by the wall clock, or by ``now``, monotonic seconds, past the seconds
        it was given: a wall clock stepped back); hand the order to the capture stage again every REFORWARD_S."""
        with self._lock:
            wall = self._wall()
            if self.pause is not None and (self.pause.until_unix <= wall or now >= self._deadline_mono):
                self._end(min(self.pause.until_unix, wall), "time", None)
            if now >= self._next_forward:
                self._next_forward = now + REFORWARD_S
                self._forward()

    def close(self) -> None:
        """The daemon stops: a running pause stays in privacy.json (a restart keeps it) and its history row is
        closed as ``stopped``."""
        with self._lock:
            if self.pause is not None and self._pause_log is not None and self._log_since is not None:
                self._log_call("end", self._wall(), "stopped", None)
            if self._pause_log is not None:
                self._log_call("close")

    def _end(self, ended_unix: float, ended: str, resumed_by: str | None) -> None:
        pause = self.pause
        if pause is None:
            return
        self.pause = None
        self._deadline_mono = float("inf")
        self.clamped = False
        self.last = EndedPause(pause.since_unix, ended_unix, pause.by, ended, resumed_by if ended == "resumed"
                               else None)
        self._save()
        self.log.info("privacy_pause_ended", ended=ended, since_unix=round(pause.since_unix, 3),
                      ended_unix=round(ended_unix, 3), by=pause.by, resumed_by=resumed_by,
                      paused_s=round(ended_unix - pause.since_unix, 1))
        if self._log_since is not None:
            self._log_call("end", ended_unix, ended, resumed_by if ended == "resumed" else None)
        self._log_since = None
        self._forward()

    # ------------------------------------------------------------------ what it says
    def status(self) -> dict:
        """The status's ``privacy``: allow_pause, max_pause_s, paused; while paused since_unix, until_unix,
        remaining_s (seconds) and by; ``last`` once a pause ended; ``save_error`` when privacy.json fails."""
        with self._lock:
            now = self._wall()
            out: dict = {"allow_pause": self.cfg.allow_pause, "max_pause_s": float(self.cfg.max_pause_s),
                         "paused": self.pause is not None}
            if self.pause is not None:
                out.update(since_unix=round(self.pause.since_unix, 3), until_unix=round(self.pause.until_unix, 3),
                           remaining_s=round(self.pause.remaining_s(now), 1), by=self.pause.by)
            if self.last is not None:
                last = self.last
                out["last"] = {"since_unix": round(last.since_unix, 3), "ended_unix": round(last.ended_unix, 3),
                               "by": last.by, "ended": last.ended, "resumed_by": last.resumed_by}
            if self.save_error is not None:
                out["save_error"] = self.save_error
            return out

    def message(self) -> dict:
        """The ``posed.privacy`` message of the state now (as a reply says it)."""
        with self._lock:
            return self._message(self._wall(), self.clamped)

    def _message(self, now: float, clamped: bool) -> dict:
        p = self.pause
        return {"format": "posed.privacy", "version": 1, "robot": self.robot, "time_unix": round(now, 4),
                "paused": p is not None, "since_unix": round(p.since_unix, 3) if p else None,
                "until_unix": round(p.until_unix, 3) if p else None, "by": p.by if p else None,
                "remaining_s": round(p.remaining_s(now), 1) if p else None,
                "clamped": bool(clamped and p is not None), "max_pause_s": float(self.cfg.max_pause_s)}

    # ------------------------------------------------------------------ keeping and handing on
    def _save(self) -> None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_privacy_file(self.path, self.pause, self.last)
        except OSError as exc:
            if self.save_error != str(exc):
                self.log.error("privacy_file_not_saved", file=str(self.path), error=str(exc),
                               fix="make pipeline.state_dir writable; the pause holds, but a restart during it "
                                   "would start watching early")
            self.save_error = str(exc)
            return
        self.save_error = None

    def _forward(self) -> None:
        if self._mailbox is None:
            return
        try:
            self._mailbox.put(PrivacyOrder(self.pause))
        except Exception as exc:        # the capture stage then goes on its file and clock; said once
            if self._mailbox_error != str(exc):
                self._mailbox_error = str(exc)
                self.log.error("privacy_not_forwarded", error=str(exc),
                               note="the capture stage reads privacy.json when it starts; poses are held back here")

    def _log_begin(self, since: float, until: float, by: str | None) -> None:
        self._log_since = since
        self._log_call("begin", since, until, by)

    def _log_call(self, what: str, *args) -> None:
        """A PauseLog call; it logs its own failed writes, and nothing it raises stops a pause."""
        if self._pause_log is None:
            return
        try:
            getattr(self._pause_log, what)(*args)
        except Exception as exc:
            self.log.error("pause_log_failed", call=what, error=repr(exc))
