"""Replay of recorded frames (videos, image folders): timestamps, real-time pacing and looping.

Timestamps: replay starts at the first ``read()`` (monotonic time ``t_start``, so a slow pipeline warm-up
between ``open()`` and the first read does not make frames late); a frame recorded ``rel`` seconds after the
first frame gets ``t = t_start + rel``, where ``rel`` comes from the timestamps sidecar when there is one,
else from the container's presentation timestamps (PTS minus the first PTS), else from ``index / fps``.
Replay is therefore deterministic relative to its start, and with ``realtime`` (frames are held back until
their ``t``) ``now - t`` measures the pipeline's latency as it would live. Without ``realtime`` frames are
handed out as fast as they are read and ``t`` still follows the recording.

Looping: the next pass continues the time line (``rel`` plus the duration of the passes before) and ``seq``
(plus one more than the last seq of the pass before), so ``t`` and ``seq`` keep increasing.

Clock jumps: the time line goes through :class:`hal.clock.ReplayClock`, so a recorded timestamp that repeats,
goes back, or leaps more than a minute forward never reaches ``t``: that frame comes one frame period after the
one before (counted as ``clock_jumps``), paced or not, and the frames after it keep their recorded steps.
"""

from __future__ import annotations

import abc
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from posed.camera_model import Intrinsics
from posed.hal.clock import ReplayClock, wait_until_due
from posed.hal.config import SourceConfig
from posed.hal.errors import EndOfStream, SourceCorrupt
from posed.hal.frame import Frame
from posed.hal.sidecar import Timestamps, read_sidecar, sidecar_path
from posed.hal.source import Source


class MediaEnd(Exception):
    """Raised by ``_next_raw`` when the media has no more frames (internal to the replay sources)."""


def config_intrinsics(config: SourceConfig, width: int, height: int) -> Intrinsics | None:
    """Intrinsics from ``source.fx/fy/cx/cy`` in pixels of the delivered image, or None when fx is 0."""
    if config.fx <= 0.0:
        return None
    return Intrinsics(fx=config.fx, fy=config.fy or config.fx, cx=config.cx or (width - 1) / 2.0,
                      cy=config.cy or (height - 1) / 2.0, width=int(width), height=int(height))


def as_bgr(image: np.ndarray) -> np.ndarray:
    """An 8-bit 3-channel BGR image from what a decoder gave (grey, BGRA, 16-bit)."""
    import cv2

    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)
    elif image.dtype != np.uint8:
        image = np.clip(image, 0, 255).astype(np.uint8)
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    if image.shape[2] == 1:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return image


def fourcc_text(value: float | None) -> str:
    """The four characters of an OpenCV ``CAP_PROP_FOURCC`` value ("MJPG", "FFV1"), or "" when it is unknown."""
    code = int(value) if value and value > 0 else 0
    return "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)).strip("\0 ") if code else ""


class Timeline:
    """The time line of one replay, from ``open()``: start, pending frame, real-time pacing, passes.

    A frame ``rel`` seconds after the recording's first frame gets ``t = t_start + t_offset + rel`` (monotonic
    seconds; ``t_start`` is the first read, ``t_offset`` the length of the passes before) and
    ``seq = seq_offset + seq_in_pass``. Used by :class:`ReplaySource` and by RealSense playback (a
    live RealSense camera uses only the seq part and the pending frame).
    """

    def __init__(self, name: str, clock: Callable[[], float], sleep: Callable[[float], None]) -> None:
        self.name = name
        self._clock = clock
        self._sleep = sleep
        self.t_start: float | None = None
        self.t_offset = 0.0                      # seconds: duration of the passes before this one
        self.seq_offset = 0                      # added to the seq within this pass
        self.first_stamp: float | None = None    # seconds: the recording's first timestamp (PTS, device time)
        self.last_rel = 0.0
        self.last_seq = -1
        self.pass_frames = 0
        self.pending: Frame | None = None        # produced, not yet handed out (its read timed out waiting)
        self.ended = False
        self.clock = ReplayClock()               # repeated, backward and leaping timestamps (clock jumps)
        self.bad_due: float | None = None        # when the last frame that did not decode was due

    def read(self, timeout_s: float, produce: Callable[[float], Frame], realtime: bool,
             period_s: float | None = None) -> Frame:
        """The pending frame, else ``produce(deadline)``; with ``realtime`` held back until its ``t`` (but not
        past ``timeout_s``: then SourceTimeout and the frame stays pending). The first call starts the line.
        With ``realtime`` and ``period_s``, a frame that cannot be decoded (SourceCorrupt from ``produce``) takes
        its frame period too, as a camera's bad frame would: the error is raised one period after the frame
        before (or the bad one before), not at once, so a replay of bad frames lasts as long as the recording."""
        now = self._clock()
        deadline = now + timeout_s
        if self.t_start is None:
            self.t_start = now
        if self.pending is None:
            try:
                self.pending = produce(deadline)
            except SourceCorrupt:
                if realtime and period_s:
                    last = self.clock.last if self.clock.last is not None else self.t_start - period_s
                    self.bad_due = max(last, self.bad_due if self.bad_due is not None else last) + period_s
                    self._sleep(max(0.0, min(self.bad_due, deadline) - self._clock()))
                raise
        frame = self.pending
        if realtime:
            wait_until_due(frame.t, deadline, timeout_s, self.name, self._clock, self._sleep)
        self.pending = None
        return frame

    def since_first(self, stamp_s: float) -> float:
        """Seconds from the recording's first timestamp to ``stamp_s`` (the first call sets it; negative for a
        stamp before it: a clock that went back, which :meth:`time_at` turns into a clock jump)."""
        if self.first_stamp is None:
            self.first_stamp = stamp_s
        return stamp_s - self.first_stamp

    def time_at(self, rel: float, period_s: float = 1.0 / 30.0) -> float:
        """Monotonic ``t`` (seconds) of the frame ``rel`` seconds after the recording's first one, in this pass;
        a clock jump (:class:`hal.clock.ReplayClock`) puts it ``period_s`` after the frame before."""
        assert self.t_start is not None
        self.last_rel = rel
        return self.clock.map(self.t_start + self.t_offset + rel, period_s)

    def add_frame(self, seq_in_pass: int) -> int:
        """Count a frame of this pass; its ``seq`` over all passes."""
        self.pass_frames += 1
        self.last_seq = self.seq_offset + seq_in_pass
        return self.last_seq

    def continue_seq(self) -> None:
        """Seq from now on continues after the last one handed out (a new pass, a restarted frame counter)."""
        self.seq_offset = self.last_seq + 1

    def end_of_pass(self, loop: bool, frame_period: Callable[[], float]) -> bool:
        """The recording ran out. With ``loop`` and frames in this pass, start the next one: its time line
        continues ``frame_period()`` seconds after the last frame, and seq after the last seq; True. Otherwise
        the replay has ``ended``; False."""
        if not loop or self.pass_frames == 0:
            self.ended = True
            return False
        self.t_offset += self.last_rel + frame_period()
        self.continue_seq()
        self.pass_frames = 0
        return True


class ReplaySource(Source):
    """Base of the file replay sources. Subclasses implement ``_open_media``, ``_close_media``,
    ``_rewind`` and ``_next_raw(deadline) -> (image BGR, index, pts_s | None)``."""

    kind = "file"

    def __init__(self, config: SourceConfig, path: str, clock=time.monotonic, sleep=time.sleep) -> None:
        super().__init__(config, f"file:{path}")
        self.path = path
        self._clock = clock
        self._sleep = sleep
        self.nominal_fps = 0.0
        self.size: tuple[int, int] | None = None
        self.sidecar: Timestamps | None = None
        self.counters.update(corrupt=0, passes=0, clock_jumps=0)

    # -- subclass hooks -----------------------------------------------------------------------------------
    @abc.abstractmethod
    def _open_media(self) -> None: ...

    @abc.abstractmethod
    def _close_media(self) -> None: ...

    @abc.abstractmethod
    def _rewind(self) -> None: ...

    @abc.abstractmethod
    def _next_raw(self, deadline: float) -> tuple[np.ndarray, int, float | None]: ...

    # -- Source -------------------------------------------------------------------------------------------
    def _open(self) -> None:
        self._open_media()
        side = sidecar_path(self.path)
        self.sidecar = read_sidecar(side) if side.is_file() else None
        self._timeline = Timeline(self.name, self._clock, self._sleep)
        self.state = "streaming"

    def _close(self) -> None:
        self._close_media()

    def _describe(self) -> dict[str, Any]:
        w, h = self.size or (0, 0)
        return {"path": self.path, "width": w, "height": h, "fps": self.nominal_fps, "has_depth": False,
                "realtime": self.config.realtime, "loop": self.config.loop,
                "timestamps": "sidecar" if self.sidecar else "pts",
                "sidecar": self.sidecar.path if self.sidecar else None}

    def _read(self, timeout_s: float) -> Frame:
        return self._timeline.read(timeout_s, self._produce, self.config.realtime, self._frame_period())

    # -- internals ----------------------------------------------------------------------------------------
    def _frame_period(self) -> float:
        return 1.0 / self.nominal_fps if self.nominal_fps > 0 else 1.0 / self.config.fps

    def _produce(self, deadline: float) -> Frame:
        line = self._timeline
        if line.ended:
            raise EndOfStream(f"{self.name}: end of the recording (set source.loop=true or ?loop=true to "
                              "replay it again)", self.name)
        while True:
            try:
                image, index, pts = self._next_raw(deadline)
            except MediaEnd:
                if not line.end_of_pass(self.config.loop, self._frame_period):
                    self.state = "ended"
                    if self.counters["passes"] == 0 and line.pass_frames == 0:
                        # looping would not help: nothing in it could be read (each bad frame was said)
                        raise EndOfStream(f"{self.name}: the recording has no readable frames ({self.counters['corrupt']} "
                                          "could not be used, each named in its own error); replace or re-record it",
                                          self.name) from None
                    raise EndOfStream(f"{self.name}: the recording ended after {self.counters['frames']} "
                                      "frames (set source.loop=true or ?loop=true to replay it again)",
                                      self.name) from None
                self.count("passes")
                self._rewind()
                continue
            rel, seq_in_pass = self._timing(index, pts)
            t, seq = line.time_at(rel, self._frame_period()), line.add_frame(seq_in_pass)
            self.counters["clock_jumps"] = line.clock.jumps
            intr = config_intrinsics(self.config, image.shape[1], image.shape[0])
            if intr is None and self.sidecar is not None and self.sidecar.intrinsics is not None:
                si = self.sidecar.intrinsics
                intr = si.scaled(image.shape[1], image.shape[0])
            return Frame(image=image, depth=None, depth_scale=0.0, t=t, seq=seq, intrinsics=intr)

    def _timing(self, index: int, pts: float | None) -> tuple[float, int]:
        """(seconds since the first frame, seq within this pass) of the frame at file ``index``."""
        if self.sidecar is not None:
            hit = self.sidecar.lookup(index)
            if hit is not None:
                seq, rel = hit
                return rel, seq
        if pts is not None:
            return self._timeline.since_first(pts), index
        return index * self._frame_period(), index
