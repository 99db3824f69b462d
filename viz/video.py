"""Writing the rendered video, and the progress bar of long renders.

Codecs, by the output's suffix (what this OpenCV build can write and a browser plays): ``.webm`` VP8 (every
current browser plays it; opencv-python-headless's FFmpeg has no H.264 encoder, so ``.mp4`` is written as
H.264 only when ``ffmpeg`` is installed — frames are piped to it — and refused otherwise, naming ``.webm``);
``.avi`` Motion-JPEG (plays in desktop players, not in browsers).

A full disk: OpenCV's writer says nothing when a write fails, so before each frame the free space of the
output's folder is checked against what a frame takes (twice the largest so far, a guess from the frame size
before the first) plus ``DISK_RESERVE_BYTES``, and at close the file is opened again and its frames counted
(ffmpeg's exit status for ``.mp4``). A video that did not make it whole is removed and :class:`DiskFullError`
(or :class:`VideoError`) raised: no empty or cut file is left looking like a render.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TextIO

import cv2
import numpy as np

SUFFIXES = (".webm", ".mp4", ".avi")
DISK_RESERVE_BYTES = 256 * 1024     # kept free: the container's index and cues written at close, buffers
FIRST_GUESS = 0.25                  # a first frame's encoded size as a fraction of its raw size (generous)


# What OpenCV's FFmpeg writer prints (with C's fprintf, past Python and OpenCV's log level) for every WebM file:
# the WebM muxer has no table of codec tags, so the VP8 tag it was given "is not supported" and it goes on with
# the codec id, writing a correct VP8 WebM. No fourcc avoids it. Only these lines are dropped, only while the
# writer opens; anything else it prints passes through.
_KNOWN_NOTES = re.compile(rb"^OpenCV: FFMPEG: (tag 0x[0-9a-f]{8}/'.{4}' is not supported with codec id \d+ and "
                          rb"format 'webm / WebM'|fallback to use tag 0x[0-9a-f]{8}/'.{4}')$")


@contextlib.contextmanager
def _known_notes_filtered():
    """Standard error (the file descriptor, where C code writes) captured while the block runs, then written
    back without the lines ``_KNOWN_NOTES`` matches."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):   # no usable descriptor 2: nothing to filter
        yield
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            rest = [line for line in tmp.read().splitlines(keepends=True)
                    if not _KNOWN_NOTES.match(line.rstrip(b"\r\n"))]
            if rest:
                os.write(2, b"".join(rest))


class VideoError(Exception):
    """The output cannot be written (the message names the fix)."""


class DiskFullError(VideoError):
    """The output's disk is full (the message names the folder); the partial file was removed."""


def _free_bytes(folder: Path) -> int | None:
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


class VideoOut:
    """Frames (BGR uint8, all of one size) to a video file at ``fps``; a context manager."""

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int]) -> None:
        self.path = Path(path)
        self.size = (int(size[0]) // 2 * 2, int(size[1]) // 2 * 2)   # even sizes: every codec takes them
        self.frames = 0
        self._largest = 0                 # the most bytes one frame took in the file so far
        self._grown = (0, 0)              # (file size, frames) when the file last grew
        self._writer = None
        self._ffmpeg: subprocess.Popen | None = None
        suffix = self.path.suffix.lower()
        if suffix not in SUFFIXES:
            raise VideoError(f"{self.path}: unknown video type {suffix or '(none)'}; use one of "
                             f"{', '.join(SUFFIXES)} (.webm plays in every browser)")
        if not self.path.parent.is_dir():
            raise VideoError(f"{self.path}: the folder {self.path.parent} does not exist")
        if suffix == ".mp4":
            exe = shutil.which("ffmpeg")
            if exe is None:
                raise VideoError(f"{self.path}: writing H.264 (.mp4) needs ffmpeg (apt-get install ffmpeg); "
                                 "this OpenCV has no H.264 encoder. Or write .webm (VP8), which browsers play")
            self._ffmpeg = subprocess.Popen(
                [exe, "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s",
                 f"{self.size[0]}x{self.size[1]}", "-r", f"{fps:.6g}", "-i", "-", "-c:v", "libx264",
                 "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(self.path)], stdin=subprocess.PIPE)
        else:
            fourcc = cv2.VideoWriter_fourcc(*("VP80" if suffix == ".webm" else "MJPG"))
            with _known_notes_filtered():
                self._writer = cv2.VideoWriter(str(self.path), fourcc, float(fps), self.size)
            if not self._writer.isOpened():
                raise VideoError(f"{self.path}: OpenCV cannot open a {suffix} writer here; try another of "
                                 f"{', '.join(SUFFIXES)}")

    def _disk_full(self, what: str) -> DiskFullError:
        folder = self.path.parent.resolve()
        return DiskFullError(f"disk full at {folder}: {self.path} {what}; free space there or write elsewhere "
                             "(the partial file was removed)")

    def write(self, frame: np.ndarray) -> None:
        if (frame.shape[1], frame.shape[0]) != self.size:
            frame = np.ascontiguousarray(frame[: self.size[1], : self.size[0]])
        need = 2 * self._largest if self._largest else int(frame.nbytes * FIRST_GUESS)
        free = _free_bytes(self.path.parent)
        if free is not None and free < need + DISK_RESERVE_BYTES:
            raise self._disk_full(f"could not be written after {self.frames} frames")
        if self._ffmpeg is not None:
            try:
                self._ffmpeg.stdin.write(frame.tobytes())
            except BrokenPipeError:
                raise VideoError(f"{self.path}: ffmpeg stopped (see its message above)") from None
        else:
            self._writer.write(frame)
        self.frames += 1
        try:
            size = self.path.stat().st_size
        except OSError:
            return
        last_size, last_frames = self._grown
        if size > last_size:             # the muxer writes in blocks: the growth shared by the frames since
            self._largest = max(self._largest, (size - last_size) // max(1, self.frames - last_frames))
            self._grown = (size, self.frames)

    def close(self) -> None:
        """Finish the file and check that it holds every frame written; if not, remove it and raise
        DiskFullError (the disk is nearly full) or VideoError."""
        failed = ""
        if self._ffmpeg is not None:
            try:
                self._ffmpeg.stdin.close()
            except BrokenPipeError:
                pass
            if self._ffmpeg.wait() != 0:
                failed = f"ffmpeg failed (exit {self._ffmpeg.returncode})"
            self._ffmpeg = None
        if self._writer is not None:
            self._writer.release()
            self._writer = None
            if self.frames and not failed:
                got = self._frames_in_file()
                if got < self.frames:
                    failed = f"holds {got} of the {self.frames} frames written"
        if failed:
            self._remove()
            free = _free_bytes(self.path.parent)
            if free is not None and free < DISK_RESERVE_BYTES + 2 * self._largest:
                raise self._disk_full(f"could not be written ({failed})")
            raise VideoError(f"{self.path}: {failed}; the file was removed")

    def _frames_in_file(self) -> int:
        """The frames the finished file holds: its frame count, counted one by one when that says fewer
        than were written."""
        try:
            if self.path.stat().st_size == 0:
                return 0
        except OSError:
            return 0
        cap = cv2.VideoCapture(str(self.path))
        try:
            if not cap.isOpened():
                return 0
            n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
            if n < self.frames:       # a count estimated from the duration may be a frame or two short:
                cap.set(cv2.CAP_PROP_POS_FRAMES, self.frames - 1)    # the last frame read settles it; else
                if n >= self.frames - 2 and cap.grab():              # (no count: no index) count them
                    return self.frames
                cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                n = 0
                while n < self.frames and cap.grab():
                    n += 1
            return n
        finally:
            cap.release()

    def _remove(self) -> None:
        with contextlib.suppress(OSError):
            self.path.unlink()

    def abort(self) -> None:
        """Stop without finishing: the partial file is removed."""
        if self._ffmpeg is not None:
            with contextlib.suppress(OSError):
                self._ffmpeg.stdin.close()
            self._ffmpeg.kill()
            self._ffmpeg.wait()
            self._ffmpeg = None
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._remove()

    def __enter__(self) -> VideoOut:
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is not None:
            self.abort()
        else:
            self.close()


class Progress:
    """A one-line progress bar on ``stream`` (standard error), redrawn at most 5 times a second; silent
    unless ``enabled``."""

    def __init__(self, total: int | None, label: str, enabled: bool, stream: TextIO = sys.stderr) -> None:
        self.total, self.label, self.enabled, self.stream = total, label, enabled, stream
        self.done = 0
        self._last = 0.0

    def step(self, n: int = 1) -> None:
        self.done += n
        now = time.monotonic()
        if self.enabled and (now - self._last >= 0.2 or self.done == self.total):
            self._last = now
            self._draw()

    def _draw(self) -> None:
        if self.total:
            frac = min(1.0, self.done / self.total)
            bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
            self.stream.write(f"\r{self.label} [{bar}] {self.done}/{self.total}")
        else:
            self.stream.write(f"\r{self.label} {self.done} frames")
        self.stream.flush()

    def finish(self) -> None:
        if self.enabled:
            self._draw()
            self.stream.write("\n")
            self.stream.flush()
