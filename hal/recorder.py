"""Save what a source sees so that a field problem can be replayed (``posed record``).

The output format follows the name given:

=====================  ===========================================================================
``NAME.mkv``           FFV1 video (lossless) + ``NAME.timestamps.jsonl``
``NAME.avi``           MJPG video + sidecar (small, lossy)
``NAME.mp4``           MPEG-4 part 2 video + sidecar (small, lossy)
``NAME.db3``           RealSense recording: colour + depth aligned to colour, intrinsics, depth scale, and
                       the accelerometer's gravity (one sample per frame that carried it)
                       (needs intrinsics: a RealSense source, or source.fx for others)
``NAME`` (no suffix)   a folder of PNG images + ``NAME/timestamps.jsonl``
=====================  ===========================================================================

The sidecar (:mod:`hal.sidecar`) keeps each frame's seq and capture time; ``file:NAME.mkv`` replays them.
Depth is kept only in ``.db3``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from posed.hal.errors import EndOfStream, SourceCorrupt, SourceDisconnected, SourceTimeout, SourceUnsupported
from posed.hal.frame import Frame
from posed.hal.imu import G_M_S2
from posed.hal.sidecar import SidecarWriter, sidecar_path
from posed.hal.source import Source

VIDEO_CODECS = {".mkv": "FFV1", ".avi": "MJPG", ".mp4": "mp4v"}


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

    def write(self, frame: Frame) -> None: ...

    def close(self) -> None: ...


class _VideoSink(_Sink):
    format = "video"

    def __init__(self, path: Path, first: Frame, fps: float, source: str) -> None:
        codec = VIDEO_CODECS[path.suffix.lower()]
        self.size = (first.width, first.height)
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

    def close(self) -> None:
        self.writer.release()
        self.side.close()


class _ImageSink(_Sink):
    format = "images"

    def __init__(self, path: Path, first: Frame, fps: float, source: str) -> None:
        path.mkdir(parents=True, exist_ok=True)
        self.folder = path
        self.size = (first.width, first.height)
        side = sidecar_path(path)
        self.sidecar = str(side)
        self.side = SidecarWriter(side, source, fps, self.size, first.intrinsics)
        self.t0 = first.t
        self.index = 0
        if first.depth is not None:
            self.notes = ("depth is not saved in an image folder; record to NAME.db3 to keep it",)

    def write(self, frame: Frame) -> None:
        name = self.folder / f"frame_{self.index:06d}.png"
        if not cv2.imwrite(str(name), frame.image):
            raise OSError(f"{name}: cannot write the image (disk full or no permission?)")
        self.side.add(self.index, frame.seq, frame.t - self.t0)
        self.index += 1

    def close(self) -> None:
        self.side.close()


class _Db3Sink(_Sink):
    format = "db3"

    def __init__(self, path: Path, first: Frame, fps: float, source: str) -> None:
        from posed.hal.db3 import Db3Writer

        if first.intrinsics is None:
            raise SourceUnsupported(f"{path}: a RealSense recording needs the camera intrinsics and {source} has "
                                    "none; set source.fx (and fy/cx/cy) or record to a video instead", str(path))
        k = first.intrinsics
        if (k.width, k.height) != (first.width, first.height):
            k = k.scaled(first.width, first.height)
        self.has_depth = first.depth is not None
        # always an accelerometer stream: the first frames of an IMU carry no gravity yet (hal.imu.MIN_SAMPLES)
        self.writer = Db3Writer(path, k, fps, depth_scale=first.depth_scale if self.has_depth else None,
                                accel_fps=max(1, int(round(fps))))
        self.t0 = first.t
        self.size = (first.width, first.height)

    def write(self, frame: Frame) -> None:
        depth = frame.depth if self.has_depth else None
        if self.has_depth and depth is None:
            depth = np.zeros((frame.height, frame.width), np.uint16)  # a frame without depth: 0 = unknown
        t_ms = (frame.t - self.t0) * 1000.0
        if frame.gravity is not None:  # before the colour frame: playback folds samples up to its time
            self.writer.write_accel(t_ms, tuple(-G_M_S2 * c for c in frame.gravity))
        self.writer.write(frame.image, depth, t_ms, frame.seq)

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
    fps = float(source.info.get("fps") or source.config.fps)
    start = clock()
    end = start + seconds if seconds is not None else None
    sink: _Sink | None = None
    problems: dict[str, int] = {}
    frames = 0
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
            if sink is None:
                sink = sink_type(path, frame, fps, source.name)
            sink.write(frame)
            frames += 1
    except KeyboardInterrupt:
        reason = "interrupted"
    finally:
        if sink is not None:
            sink.close()
    return RecordSummary(path=str(path), format=sink.format if sink else "", frames=frames,
                         seconds=clock() - start, reason=reason, sidecar=sink.sidecar if sink else None,
                         has_depth=bool(sink and sink.has_depth), problems=problems,
                         notes=sink.notes if sink else ())
