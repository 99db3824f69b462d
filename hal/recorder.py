"""Save what a source sees so that a field problem can be replayed (``posed record``).

The output format follows the name given:

=====================  ===========================================================================
``NAME.mkv``           FFV1 video (lossless) + ``NAME.timestamps.jsonl``
``NAME.avi``           MJPG video + sidecar (small, lossy)
``NAME.mp4``           MPEG-4 part 2 video + sidecar (small, lossy)
``NAME.db3``           RealSense recording: colour + depth aligned to colour, intrinsics, depth scale, and
                       the accelerometer's gravity (one sample per frame that carried it; from a camera
                       with a gyro, its turn between frames as a gyro stream too)
                       (needs intrinsics: a RealSense source, or source.fx for others)
``NAME`` (no suffix)   a folder of PNG images + ``NAME/timestamps.jsonl``
=====================  ===========================================================================

Infrared frames (a RealSense in a dark room, ``Frame.spectrum`` ``infrared``, :mod:`hal.night`): a ``.db3``
from a source that streams an infrared image (``info["infrared"]`` standby or in use) gets an infrared stream
at the source's infrared intrinsics. Each frame writes one image to each stream: an infrared frame its image to
the infrared stream, a black frame to colour and depth 0 (its depth lies on the infrared imager's grid, not on
the recording's colour one: not kept); a colour frame its image and depth as before and a black infrared image.
A replay (``source.infrared`` auto) then chooses the same image for every frame as the camera did: a black
colour frame is dark. Gravity is written as each frame carried it (an infrared frame's in the infrared imager's
axes, within a degree of the colour camera's on a D4xx). A video or image folder has one image per frame: infrared frames are written as they
came (grey) and the summary's notes say how many there were.

The sidecar (:mod:`hal.sidecar`) keeps each frame's seq and capture time; ``file:NAME.mkv`` replays them.
Depth is kept only in ``.db3``. The output's folder is created when it does not exist.

A full disk (OpenCV's video writer says nothing when a write fails): before each frame the free space of the
output's folder is checked against what the frame may take (``_Sink.need``: the largest frame so far, twice;
before the first, a guess from the image size) plus ``DISK_RESERVE_BYTES`` for the container's index and what is still
buffered. Recording stops before the first frame that would not fit (``reason`` "disk full"), so the file
is finished and plays; at close a video is opened again and its frames counted, and should fewer have reached
the disk than were written, ``frames`` and the sidecar are cut to those the file holds.
"""

from __future__ import annotations

import errno
import math
import os
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from posed.camera_model import Intrinsics
from posed.hal.errors import EndOfStream, SourceCorrupt, SourceDisconnected, SourceTimeout, SourceUnsupported
from posed.hal.frame import Frame
from posed.hal.imu import G_M_S2
from posed.hal.sidecar import SidecarWriter, sidecar_path
from posed.hal.source import Source

VIDEO_CODECS = {".mkv": "FFV1", ".avi": "MJPG", ".mp4": "mp4v"}
# a first guess of a frame's encoded size, as a fraction of its raw BGR size (generous: a guess too small
# lets one frame be lost; too large only stops a recording on a nearly full disk a frame early)
GYRO_STEP_S = 0.05        # a recording's gyro samples are at most this far apart (hal.imu.GYRO_MAX_GAP_S is 0.1 s)
FIRST_GUESS = {"FFV1": 1.0, "MJPG": 0.2, "mp4v": 0.2, "png": 0.8, "db3": 1.0}
DISK_RESERVE_BYTES = 256 * 1024     # kept free: the index written at close, buffered output, sidecar lines
DISK_FULL = "disk full"


class _DiskFull(Exception):
    """The output's disk cannot take the next frame."""


def free_bytes(folder: str | os.PathLike) -> int | None:
    """Bytes an unprivileged writer may still use on ``folder``'s file system (None: cannot tell)."""
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


def _is_disk_full(exc: BaseException) -> bool:
    return getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT) or "disk is full" in str(exc).lower()


@dataclass(frozen=True)
class RecordSummary:
    """What ``record`` wrote and what happened on the way."""

    path: str
    format: str
    frames: int
    seconds: float
    reason: str
    sidecar: str | None = None
    has_depth: bool = False
    problems: dict[str, int] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {"path": self.path, "format": self.format, "frames": self.frames, "seconds": round(self.seconds, 3),
                "reason": self.reason, "sidecar": self.sidecar, "has_depth": self.has_depth,
                "problems": dict(self.problems), "notes": list(self.notes)}


class _Sink:
    format = ""
    sidecar: str | None = None
    has_depth = False
    notes: tuple[str, ...] = ()
    largest = 0          # the most bytes one frame took on disk so far (0: not measured yet)
    guess = 0            # the first guess of a frame's size (FIRST_GUESS)

    def infrared_note(self, n: int) -> str:
        """What became of the ``n`` infrared frames written (module doc)."""
        return (f"{n} frames were infrared images (a dark room; hal.night): written as the grey images they are, "
                "so a replay shows them as ordinary frames; record to NAME.db3 to keep them as infrared")

    def write(self, frame: Frame) -> None: ...

    def close(self) -> None: ...

    def need(self) -> int:
        """Bytes the next frame may take on disk: twice the largest so far, the first guess before any."""
        return (2 * self.largest if self.largest else self.guess) + 128       # + its sidecar line

    def kept(self, written: int) -> int:
        """After close: how many of the ``written`` frames the output holds (a video is counted again)."""
        return written


def _guess(frame: Frame, kind: str) -> int:
    raw = frame.width * frame.height * 3 + (0 if frame.depth is None else frame.depth.nbytes)
    return int(raw * FIRST_GUESS[kind])


class _VideoSink(_Sink):
    format = "video"

    def __init__(self, path: Path, first: Frame, fps: float, source: str) -> None:
        codec = VIDEO_CODECS[path.suffix.lower()]
        self.path = path
        self.size = (first.width, first.height)
        self.guess = _guess(first, codec)
        self._measured = (0, 0)          # (file size, frames) when the file last grew
        self.writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*codec), fps, self.size)
        if not self.writer.isOpened():
            raise SourceUnsupported(f"{path}: OpenCV cannot write {codec} video here; try another suffix "
                                    f"({', '.join(VIDEO_CODECS)}) or a folder name", str(path))
        side = sidecar_path(path)
        self.sidecar = str(side)
        self.side = SidecarWriter(side, source, fps, self.size, first.intrinsics)
        self.t0 = first.t
        self.index = 0
        self.has_depth = False
        if first.depth is not None:
            self.notes = ("depth is not saved in a video; record to NAME.db3 to keep it",)

    def write(self, frame: Frame) -> None:
        image = frame.image
        if (frame.width, frame.height) != self.size:
            image = cv2.resize(image, self.size, interpolation=cv2.INTER_AREA)
        self.writer.write(image)
        self.side.add(self.index, frame.seq, frame.t - self.t0)
        self.index += 1
        try:
            size = self.path.stat().st_size
        except OSError:
            return
        last_size, last_frames = self._measured
        if size > last_size:          # the muxer writes in blocks: the growth shared by the frames since
            self.largest = max(self.largest, (size - last_size) // max(1, self.index - last_frames))
            self._measured = (size, self.index)

    def close(self) -> None:
        self.writer.release()
        self.side.close()

    def kept(self, written: int) -> int:
        """The frames the finished file holds: its frame count, or when that says fewer than were written
        (or nothing), the frames read back one by one; the sidecar is cut to match."""
        if written == 0:
            return 0
        cap = cv2.VideoCapture(str(self.path))
        try:
            n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if cap.isOpened() else 0
            if n < written and cap.isOpened():   # a count estimated from the duration may be a frame or two
                cap.set(cv2.CAP_PROP_POS_FRAMES, written - 1)      # short: the last frame read settles it;
                if n >= written - 2 and cap.grab():                # else (no count: no index) count them
                    n = written
                else:
                    cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
                    n = 0
                    while n < written and cap.grab():
                        n += 1
        finally:
            cap.release()
        n = min(n, written)
        if n < written:
            self.side.keep(n)
        return n


class _ImageSink(_Sink):
    format = "images"

    def __init__(self, path: Path, first: Frame, fps: float, source: str) -> None:
        path.mkdir(parents=True, exist_ok=True)
        self.folder = path
        self.size = (first.width, first.height)
        self.guess = _guess(first, "png")
        side = sidecar_path(path)
        self.sidecar = str(side)
        self.side = SidecarWriter(side, source, fps, self.size, first.intrinsics)
        self.t0 = first.t
        self.index = 0
        if first.depth is not None:
            self.notes = ("depth is not saved in an image folder; record to NAME.db3 to keep it",)

    def write(self, frame: Frame) -> None:
        name = self.folder / f"frame_{self.index:06d}.png"
        ok = cv2.imwrite(str(name), frame.image)
        try:
            size = name.stat().st_size
        except OSError:
            size = 0
        if not ok or size == 0:
            name.unlink(missing_ok=True)             # a cut image would break the replay
            free = free_bytes(self.folder)
            if free is not None and free < self.need():
                raise _DiskFull(str(name))
            raise OSError(f"{name}: cannot write the image (no permission?)")
        self.largest = max(self.largest, size)
        self.side.add(self.index, frame.seq, frame.t - self.t0)
        self.index += 1

    def close(self) -> None:
        self.side.close()


class _Db3Sink(_Sink):
    format = "db3"

    def __init__(self, path: Path, first: Frame, fps: float, source: str, gyro: bool = False,
                 infrared: tuple[Intrinsics, Intrinsics, float] | None = None) -> None:
        """``gyro``: the source's gravity comes with a gyro's (``info["gyro"]`` streaming): record a gyro stream
        too, the turn from each frame's gravity to the next (``write``), so that the replay's filter turns its
        average with the camera as the live one did, and gives the recorded gravity again rather than a
        low-passed copy of it. ``infrared``: (colour intrinsics, infrared intrinsics, depth scale or 0) of a source
        that streams an infrared image beside colour: an infrared stream too (module doc)."""
        from posed.hal.db3 import Db3Writer

        if first.intrinsics is None:
            raise SourceUnsupported(f"{path}: a RealSense recording needs the camera intrinsics and {source} has "
                                    "none; set source.fx (and fy/cx/cy) or record to a video instead", str(path))
        k, k_ir, scale = infrared if infrared is not None else (first.intrinsics, None, first.depth_scale)
        if (k.width, k.height) != (first.width, first.height):
            k = k.scaled(first.width, first.height)
        if k_ir is not None and (k_ir.width, k_ir.height) != (first.width, first.height):
            k_ir = k_ir.scaled(first.width, first.height)
        # the first frame may be an infrared one without depth (not on its grid): the source says
        self.has_depth = first.depth is not None or (infrared is not None and scale > 0)
        # always an accelerometer stream: the first frames of an IMU carry no gravity yet (hal.imu.MIN_SAMPLES)
        self.writer = Db3Writer(path, k, fps, depth_scale=(scale or first.depth_scale) if self.has_depth else None,
                                accel_fps=max(1, int(round(fps))),
                                gyro_fps=int(round(1.0 / GYRO_STEP_S)) if gyro else None,
                                infrared=k_ir is not None, infrared_intrinsics=k_ir)
        self.infrared = k_ir is not None
        self.gyro = gyro
        self._last_down: tuple[float, np.ndarray] | None = None   # (t_ms, unit down) of the last gravity
        self.t0 = first.t
        self.size = (first.width, first.height)
        self.guess = _guess(first, "db3")

    def write(self, frame: Frame) -> None:
        by_infrared = self.infrared and frame.spectrum == "infrared"
        depth = frame.depth if self.has_depth and not by_infrared else None   # infrared: on its own grid
        if self.has_depth and depth is None:
            depth = np.zeros((frame.height, frame.width), np.uint16)  # a frame without depth: 0 = unknown
        t_ms = (frame.t - self.t0) * 1000.0
        if frame.gravity is not None:  # before the colour frame: playback folds samples up to its time
            if self.gyro:
                self._write_turn(t_ms, np.asarray(frame.gravity, dtype=np.float64))
            self.writer.write_accel(t_ms, tuple(-G_M_S2 * c for c in frame.gravity))
        if not self.infrared:
            self.writer.write(frame.image, depth, t_ms, frame.seq)
            return
        if by_infrared:   # the grey image as BGR has three equal channels: one is the Y8 image
            self.writer.write(np.zeros_like(frame.image), depth, t_ms, frame.seq,
                              infrared=np.ascontiguousarray(frame.image[:, :, 0]))
        else:
            self.writer.write(frame.image, depth, t_ms, frame.seq,
                              infrared=np.zeros((frame.height, frame.width), np.uint8))

    def infrared_note(self, n: int) -> str:
        if not self.infrared:
            return (f"{n} frames were infrared images (a dark room; hal.night), written as colour frames: the "
                    "source had no usable infrared stream when recording began, so a replay shows them as colour")
        return (f"{n} frames were infrared images (a dark room; hal.night): kept in the infrared stream with a "
                "black colour frame, so a replay (source.infrared auto) gives them as infrared again; their depth "
                "(on the infrared imager's grid) is not kept")

    def _write_turn(self, t_ms: float, down: np.ndarray) -> None:
        """Gyro samples that turn the last frame's down into this one's: the smallest rotation between them at a
        constant rate (a down d seen from a camera turning at w moves as dd/dt = -w x d, so w is along
        -(d0 x d1)), in steps of at most ``GYRO_STEP_S`` (hal.imu integrates no longer gap); the first frame's
        sample only starts the gyro's clock. Colour axes: posed record writes depth already on the colour grid
        (identity extrinsics), so they are the depth sensor's."""
        last, self._last_down = self._last_down, (t_ms, down / float(np.linalg.norm(down)))
        if last is None:
            self.writer.write_gyro(t_ms, (0.0, 0.0, 0.0))
            return
        t0, d0 = last
        dt_s = (t_ms - t0) / 1000.0
        if not dt_s > 0:
            return
        axis = np.cross(d0, self._last_down[1])
        s = float(np.linalg.norm(axis))
        angle = math.atan2(s, float(d0 @ self._last_down[1]))
        rate = -axis / s * angle / dt_s if s > 0 else np.zeros(3)
        n = max(1, math.ceil(dt_s / GYRO_STEP_S - 1e-9))
        for i in range(1, n + 1):
            self.writer.write_gyro(t0 + (t_ms - t0) * i / n, (float(rate[0]), float(rate[1]), float(rate[2])))

    def close(self) -> None:
        self.writer.close()


def check_output(path: str) -> type[_Sink]:
    """The sink that writes the output name ``path`` (by its suffix); SourceUnsupported for a name ``record``
    cannot write, so callers can refuse it before opening the source."""
    suffix = Path(path).suffix.lower()
    if suffix == ".db3":
        return _Db3Sink
    if suffix in VIDEO_CODECS:
        return _VideoSink
    if suffix == "":
        return _ImageSink
    raise SourceUnsupported(f"{path}: cannot record to {suffix!r}; use .mkv (lossless), .avi, .mp4, .db3 "
                            "(RealSense, with depth) or a folder name", path)


def record(source: Source, output: str, seconds: float | None = None, max_frames: int | None = None,
           should_stop: Callable[[], bool] | None = None, clock=time.monotonic) -> RecordSummary:
    """Read frames from an open ``source`` into ``output`` until ``seconds`` pass, ``max_frames`` are written,
    the recording ends or ``should_stop()`` is true. Timeouts, unplugs and corrupt frames are counted and
    recording goes on; the file is finished in every case."""
    sink_type = check_output(output)
    path = Path(output)
    folder = path if sink_type is _ImageSink else path.parent
    fps = float(source.info.get("fps") or source.config.fps)
    start = clock()
    end = start + seconds if seconds is not None else None
    sink: _Sink | None = None
    problems: dict[str, int] = {}
    frames = 0
    infrared_frames = 0
    reason = "stopped"
    try:
        while True:
            if should_stop is not None and should_stop():
                reason = "stopped"
                break
            now = clock()
            if end is not None and now >= end:
                reason = "time"
                break
            if max_frames is not None and frames >= max_frames:
                reason = "frames"
                break
            timeout = source.config.read_timeout_s if end is None else max(0.01, min(source.config.read_timeout_s,
                                                                                     end - now))
            try:
                frame = source.read(timeout)
            except EndOfStream:
                reason = "end of stream"
                break
            except (SourceTimeout, SourceDisconnected, SourceCorrupt) as exc:
                key = type(exc).__name__
                problems[key] = problems.get(key, 0) + 1
                continue
            try:
                if sink is None:
                    if sink_type is not _ImageSink:
                        folder.mkdir(parents=True, exist_ok=True)
                    sink = sink_type(path, frame, fps, source.name, **(
                        _db3_options(dict(source.info)) if sink_type is _Db3Sink else {}))
                _check_room(folder, sink.need())
                sink.write(frame)
            except _DiskFull:
                reason = DISK_FULL
                break
            except (OSError, sqlite3.Error) as exc:
                if not _is_disk_full(exc):
                    raise
                reason = DISK_FULL
                break
            frames += 1
            infrared_frames += frame.spectrum == "infrared"
    except KeyboardInterrupt:
        reason = "interrupted"
    finally:
        if sink is not None:
            sink.close()
    notes = sink.notes if sink else ()
    if sink is not None:
        kept = sink.kept(frames)
        if kept < frames:                   # frames the disk did not take although the writer said nothing
            frames, reason = kept, DISK_FULL
        if frames == 0 and reason == DISK_FULL and isinstance(sink, _VideoSink):
            for leftover in (path, Path(sink.side.path)):     # no frame: no unplayable stub left behind
                leftover.unlink(missing_ok=True)
    if sink is not None and infrared_frames:
        notes = (*notes, sink.infrared_note(infrared_frames))
    if reason == DISK_FULL:
        notes = (*notes, f"disk full at {os.path.abspath(folder)} after {frames} frames: free space or record "
                         "elsewhere")
    return RecordSummary(path=str(path), format=sink.format if sink else "", frames=frames,
                         seconds=clock() - start, reason=reason, sidecar=sink.sidecar if sink else None,
                         has_depth=bool(sink and sink.has_depth), problems=problems, notes=notes)


def _db3_options(info: dict[str, Any]) -> dict[str, Any]:
    """What a ``.db3`` records besides colour and depth, from the source's ``info``: a gyro stream when its
    gravity comes with a gyro's, an infrared stream when it streams an infrared image."""
    out: dict[str, Any] = {"gyro": info.get("gyro") == "streaming"}
    colour, ir = info.get("intrinsics"), info.get("infrared_intrinsics")
    if info.get("infrared") in ("standby", "in use") and isinstance(colour, dict) and isinstance(ir, dict):
        scale = float(info.get("depth_scale") or 0.0) if info.get("has_depth") else 0.0
        out["infrared"] = (Intrinsics.from_json(colour), Intrinsics.from_json(ir), scale)
    return out


def _check_room(folder: Path, need: int) -> None:
    """_DiskFull when ``folder``'s file system has less than ``need`` + DISK_RESERVE_BYTES free."""
    free = free_bytes(folder)
    if free is not None and free < need + DISK_RESERVE_BYTES:
        raise _DiskFull(str(folder))
