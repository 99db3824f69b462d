"""The camera poses the robot puts on ``posed/ROBOT/camera/mount``, as the publisher stage keeps them
(``falls.camera_mount_from_bus``; docs/falls.md, "The camera's pose from the robot").

Each payload (on a Zenoh thread) is parsed (:mod:`daemon.bus.camera_mount`); its ``time_unix`` is put on the
daemon's one clock (monotonic; :func:`daemon.clock.monotonic_from_wall`; without it, when it was received),
and the sample joins the bounded, time-ordered :class:`daemon.stages.mount_samples.MountSamples`, which is
handed as a whole to the fitting stage through the ``mount`` mailbox (and again every ``REFORWARD_S``, for a
fitting stage that was restarted since). A payload that is not a camera pose, or
one dated more than ``MAX_AHEAD_S`` after it arrived (the robot's clock and this one disagree), is counted
(``rejected``, ``last_error``), logged at most 5 times a minute (:class:`daemon.proc.throttle.Throttle`), and
changes nothing. A pose that had already run out when it arrived (``time_unix + valid_s`` before its arrival: a
robot clock behind this one, or a slow link) is kept but can never be in force: counted (``late``) and said
(``camera_mount_late``, at most 5 times a minute, with the fix). The log says when the poses start, change
source or stop being in force, never per message.
"""

from __future__ import annotations

import threading

from posed.daemon import clock
from posed.daemon.bus.camera_mount import EXPECTED, BadMount, parse_camera_mount
from posed.daemon.proc.throttle import Throttle
from posed.daemon.stages.mount_samples import MountSample, MountSamples

MAX_AHEAD_S = 1.0          # a pose dated this far after its arrival is from a clock that is not this machine's
REFORWARD_S = 1.0          # the samples are handed to the fitting stage again this often (a restarted one has none)


class MountFeed:
    """``on_payload(bytes)`` for each message (any thread); ``at(t)`` the sample in force at a frame's capture time
    (the publisher's loop); ``status()`` for the status message. ``mailbox``: where the samples go to the fitting
    stage (None: nowhere)."""

    def __init__(self, log, mailbox=None, now=clock.now, from_wall=clock.monotonic_from_wall) -> None:
        self.log = log
        self._mailbox = mailbox
        self._now = now
        self._from_wall = from_wall
        self._lock = threading.Lock()
        self._throttle = Throttle()
        self.samples = MountSamples()
        self.rejected = 0
        self.late = 0                            # poses that had run out before they arrived (never in force)
        self.last_error: str | None = None
        self._said_source: tuple | None = None   # (source, with height) the log last named
        self._in_force: bool | None = None       # at the last frame
        self._mailbox_error: str | None = None
        self._next_forward = 0.0

    def on_payload(self, payload: bytes) -> None:
        """One message on the key: kept, or counted as rejected. Never raises."""
        received = self._now()
        try:
            mount = parse_camera_mount(payload)
            t = received if mount.time_unix is None else self._from_wall(mount.time_unix)
            if t > received + MAX_AHEAD_S:
                raise BadMount(f'"time_unix" is {t - received:.1f} s after the message arrived: the robot\'s clock '
                               "and this machine's disagree (synchronise them, e.g. NTP) or leave time_unix out")
        except BadMount as exc:
            self._reject(str(exc))
            return
        sample = MountSample(t, mount.valid_s, mount.down, mount.height_m, mount.source)
        if received - t > mount.valid_s:
            self._late(received - t, mount.valid_s)
        with self._lock:
            self.samples = samples = self.samples.add(sample)
            said = (mount.source, mount.height_m is not None)
            first = self._said_source is None
            changed = said != self._said_source
            self._said_source = said
        if changed:
            self.log.info("camera_mount_received" if first else "camera_mount_source_changed", source=mount.source,
                          height_given=mount.height_m is not None, valid_s=mount.valid_s, received=samples.received)
        self._forward(samples)

    def _late(self, delay_s: float, valid_s: float) -> None:
        """A pose that had already run out when it arrived: kept (it can never be in force), counted and said,
        because a robot whose every pose arrives late is one whose poses posed never uses."""
        with self._lock:
            self.late += 1
            late = self.late
        suppressed = self._throttle.allow("camera_mount_late")
        if suppressed is not None:
            self.log.warning("camera_mount_late", arrived_after_s=round(delay_s, 3), valid_s=valid_s, late=late,
                             suppressed=suppressed,
                             fix="the pose arrived after its time_unix + valid_s, so it is never used: the robot's "
                                 "clock is behind this machine's (synchronise them, e.g. NTP, or leave time_unix "
                                 "out) or the link is that slow (give a longer valid_s)")

    def _reject(self, error: str) -> None:
        with self._lock:
            self.rejected += 1
            self.last_error = error
            rejected = self.rejected
        suppressed = self._throttle.allow("bad_camera_mount")
        if suppressed is not None:
            self.log.warning("bad_camera_mount", error=error, expected=EXPECTED, rejected=rejected,
                             suppressed=suppressed)

    def _forward(self, samples: MountSamples) -> None:
        if self._mailbox is None:
            return
        try:
            self._mailbox.put(samples)
        except Exception as exc:            # the fit then goes without the robot's gravity; said once
            if self._mailbox_error != str(exc):
                self._mailbox_error = str(exc)
                self.log.error("camera_mount_not_forwarded", error=str(exc),
                               note="the fit's vertical goes without the robot's gravity; the fall detector has it")

    def reforward(self, now: float) -> None:
        """Every ``REFORWARD_S`` (the publisher's loop, monotonic seconds), hand the samples to the fitting stage
        again: a fitting stage restarted after the last pose (a mast that said where it is once, with a long
        ``valid_s``) gets them too."""
        if now < self._next_forward:
            return
        self._next_forward = now + REFORWARD_S
        if self.samples.samples:
            self._forward(self.samples)

    @property
    def received(self) -> int:
        """How many samples were accepted since the start."""
        return self.samples.received

    def at(self, t: float) -> MountSample | None:
        """The sample in force at capture time ``t``; a change between in force and not is logged once."""
        sample = self.samples.at(t)
        in_force = sample is not None
        if in_force != self._in_force and (self._in_force is not None or in_force):
            newest = self.samples.newest
            if in_force:
                self.log.info("camera_mount_in_force", source=sample.source, height_given=sample.height_m is not None)
            else:
                self.log.warning("camera_mount_not_in_force", received=self.samples.received,
                                 newest_age_s=None if newest is None else round(t - newest.t, 3),
                                 note="no pose from the robot holds at this frame's capture time: the IMU, depth "
                                      "floor, learned or configured geometry is used")
        self._in_force = in_force
        return sample

    def status(self, now: float | None = None) -> dict:
        """``received``, ``rejected``, ``late`` (poses that had run out before they arrived), ``last_error``,
        ``age_s`` (seconds since the newest sample was true, on the capture clock; None before any), ``in_force``
        (at the last frame) and ``source`` (the newest's)."""
        now = self._now() if now is None else now
        samples = self.samples
        newest = samples.newest
        return {"received": samples.received, "rejected": self.rejected, "late": self.late,
                "last_error": self.last_error,
                "age_s": None if newest is None else round(now - newest.t, 3), "in_force": bool(self._in_force),
                "source": None if newest is None else newest.source}
