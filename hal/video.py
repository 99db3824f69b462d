"""Replay of a video file decoded by OpenCV (FFMPEG backend).

A video that will not open at all (a truncated MP4 without its index, a file that is not a video) raises
SourceCorrupt at ``open()``. A decode failure before the container's last frame is corruption in the middle:
the read raises SourceCorrupt naming the file and the frames lost, and the next read goes on with the first
frame the decoder recovers (FFmpeg resynchronises at the next key frame); when nothing more decodes the
error says so and the following read raises EndOfStream (or starts the next pass with ``loop``).

A rotation tag (a phone held upright records landscape pixels and a display matrix saying "turn by 90"):
OpenCV's FFmpeg backend applies it (``CAP_PROP_ORIENTATION_AUTO``), so frames come upright and ``info``'s
size is the upright size; ``info["rotation"]`` says by how many degrees the pixels were turned.
"""

from __future__ import annotations

import os

import cv2
import numpy as np

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceNotFound
from posed.hal.replay import MediaEnd, ReplaySource, as_bgr, fourcc_text

# Reads tried after a decode failure before the rest of the file is given up (FFmpeg needed 10 on a
# damaged 5 fps H.264 test file; each failed read costs well under a millisecond).
MAX_BAD_READS = 200


class VideoFileSource(ReplaySource):
    """Frames of one video file; ``info`` adds ``frame_count`` and ``codec``."""

    def __init__(self, config: SourceConfig, path: str, **kw) -> None:
        super().__init__(config, path, **kw)
        self._cap: cv2.VideoCapture | None = None
        self.frame_count = 0
        self.codec = ""
        self.rotation = 0

    def _open_media(self) -> None:
        if not os.path.isfile(self.path):
            raise SourceNotFound(f"{self.path}: no such video file; check the path in source.path or the "
                                 "file: URI", self.name)
        cap = cv2.VideoCapture(self.path, cv2.CAP_FFMPEG)
        if not cap.isOpened():
            cap.release()
            raise SourceCorrupt(f"{self.path}: OpenCV/FFmpeg cannot open this video: it is truncated, corrupt or "
                                "in a format this build cannot decode (an MP4 cut short loses its index); check "
                                "it with `ffprobe`, re-encode or re-record it", self.name)
        self._cap = cap
        self.frame_count = max(0, int(cap.get(cv2.CAP_PROP_FRAME_COUNT)))
        fps = cap.get(cv2.CAP_PROP_FPS)
        self.nominal_fps = float(fps) if fps and fps > 0 and np.isfinite(fps) else 0.0
        self.size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.codec = fourcc_text(cap.get(cv2.CAP_PROP_FOURCC))
        # a phone video's rotation tag (the container's display matrix): OpenCV turns the frames upright itself
        # (CAP_PROP_ORIENTATION_AUTO, on by default), and the size above is already the upright one
        rot = cap.get(cv2.CAP_PROP_ORIENTATION_META)
        self.rotation = int(rot) % 360 if rot and np.isfinite(rot) else 0
        self._skip = 0           # frames the decoder lost so far (file index = decoded position + skip)
        self._bad_from: int | None = None
        self._bad_reads = 0
        self._dead = False
        self._held: tuple[np.ndarray, int, float | None] | None = None

    def _close_media(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None

    def _rewind(self) -> None:
        assert self._cap is not None
        if not self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0) or int(self._cap.get(cv2.CAP_PROP_POS_FRAMES)) != 0:
            self._cap.release()
            self._cap = cv2.VideoCapture(self.path, cv2.CAP_FFMPEG)
        self._skip = 0
        self._bad_from = None
        self._bad_reads = 0
        self._dead = False

    def _describe(self) -> dict:
        out = super()._describe()
        out.update(frame_count=self.frame_count, codec=self.codec, rotation=self.rotation)
        return out

    def _pts(self) -> float | None:
        assert self._cap is not None
        ms = self._cap.get(cv2.CAP_PROP_POS_MSEC)
        return ms / 1000.0 if ms is not None and np.isfinite(ms) and ms >= 0 else None

    def _next_raw(self, deadline: float) -> tuple[np.ndarray, int, float | None]:
        if self._held is not None:
            held, self._held = self._held, None
            return held
        if self._dead:
            raise MediaEnd
        cap = self._cap
        assert cap is not None
        while True:
            pos = int(cap.get(cv2.CAP_PROP_POS_FRAMES))
            ok, image = cap.read()
            if ok and image is not None:
                pts = self._pts()
                index = pos + self._skip
                if self._bad_from is not None:
                    return self._recovered(as_bgr(image), pos, pts)
                return as_bgr(image), index, pts
            index = pos + self._skip
            if self._bad_from is None:
                if self.frame_count <= 0 or index >= self.frame_count - 1:
                    raise MediaEnd  # a clean end (the container's count may be one too high)
                self._bad_from = index
                self._bad_reads = 0
            self._bad_reads += 1
            if self._bad_reads >= MAX_BAD_READS:
                self._dead = True
                first, self._bad_from = self._bad_from, None
                self.count("corrupt")
                raise SourceCorrupt(
                    f"{self.path}: frames {first}..{self.frame_count - 1} of {self.frame_count} cannot be decoded: "
                    "the file is corrupt or truncated from there; replay stops at its last good frame "
                    "(re-encode it with ffmpeg or re-record it)", self.name)
            if self._clock() >= deadline:
                self.count("corrupt")
                raise SourceCorrupt(f"{self.path}: frames from {self._bad_from} on cannot be decoded (corrupt "
                                    "data); still looking for the next good frame", self.name)

    def _recovered(self, image: np.ndarray, pos: int, pts: float | None) -> tuple[np.ndarray, int, float | None]:
        """The first good frame after a bad stretch: re-synchronise the index from its PTS, hold it back for the
        next read and report the frames lost."""
        first = self._bad_from
        assert first is not None
        index = pos + self._skip
        if pts is not None and self.nominal_fps > 0:
            index = max(index, round((pts - (self._timeline.first_stamp or 0.0)) * self.nominal_fps))
            self._skip = index - pos
        self._bad_from = None
        self._held = (image, index, pts)
        self.count("corrupt")
        lost = f"frames {first}..{index - 1}" if index - 1 > first else f"frame {first}"
        raise SourceCorrupt(f"{self.path}: {lost} could not be decoded (corrupt data); replay goes on at frame "
                            f"{index}", self.name)
