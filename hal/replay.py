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
"""

from __future__ import annotations

import abc
import time
from typing import Any

import numpy as np

from hal.clock import wait_until_due
from hal.config import SourceConfig
from hal.errors import EndOfStream
from hal.frame import Frame, Intrinsics
from hal.sidecar import Timestamps, read_sidecar, sidecar_path
from hal.source import Source


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
        self.counters.update(corrupt=0, passes=0)

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
        self._t_start: float | None = None
        self._t_offset = 0.0     # duration of the passes before this one
        self._seq_offset = 0     # seq added in this pass
        self._pts_first: float | None = None
        self._last_rel = 0.0
        self._last_seq = -1
        self._pass_frames = 0
        self._pending: Frame | None = None
        self._ended = False
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
        now = self._clock()
        deadline = now + timeout_s
        if self._t_start is None:
            self._t_start = now
        if self._pending is None:
            self._pending = self._produce(deadline)
        frame = self._pending
        if self.config.realtime:
            wait_until_due(frame.t, deadline, timeout_s, self.name, self._clock, self._sleep)
        self._pending = None
        return frame

    # -- internals ----------------------------------------------------------------------------------------
    def _frame_period(self) -> float:
        return 1.0 / self.nominal_fps if self.nominal_fps > 0 else 1.0 / self.config.fps

    def _produce(self, deadline: float) -> Frame:
        if self._ended:
            raise EndOfStream(f"{self.name}: end of the recording (set source.loop=true or ?loop=true to "
                              "replay it again)", self.name)
        while True:
            try:
                image, index, pts = self._next_raw(deadline)
            except MediaEnd:
                if not self.config.loop or self._pass_frames == 0:
                    self._ended = True
                    self.state = "ended"
                    what = "has no readable frames" if self.counters["passes"] == 0 and self._pass_frames == 0 \
                        else "ended"
                    raise EndOfStream(f"{self.name}: the recording {what} after {self.counters['frames']} "
                                      "frames (set source.loop=true or ?loop=true to replay it again)",
                                      self.name) from None
                self._t_offset += self._last_rel + self._frame_period()
                self._seq_offset = self._last_seq + 1
                self._pass_frames = 0
                self.count("passes")
                self._rewind()
                continue
            rel, seq = self._timing(index, pts)
            self._pass_frames += 1
            self._last_rel = rel
            self._last_seq = self._seq_offset + seq
            assert self._t_start is not None
            intr = config_intrinsics(self.config, image.shape[1], image.shape[0])
            if intr is None and self.sidecar is not None and self.sidecar.intrinsics is not None:
                si = self.sidecar.intrinsics
                intr = si.scaled(image.shape[1], image.shape[0])
            return Frame(image=image, depth=None, depth_scale=0.0, t=self._t_start + self._t_offset + rel,
                         seq=self._last_seq, intrinsics=intr)

    def _timing(self, index: int, pts: float | None) -> tuple[float, int]:
        """(seconds since the first frame, seq within this pass) of the frame at file ``index``."""
        if self.sidecar is not None:
            hit = self.sidecar.lookup(index)
            if hit is not None:
                seq, rel = hit
                return rel, seq
        if pts is not None:
            if self._pts_first is None:
                self._pts_first = pts
            return max(0.0, pts - self._pts_first), index
        return index * self._frame_period(), index
