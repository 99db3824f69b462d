"""``posed landmarks INPUT [-o OUT.landmarks.jsonl]``: the 2D landmark stage alone, on an image, a video, a
folder of images or a RealSense recording (``.db3``/``.bag``), written as a landmark recording (interfaces.md
section 1).

A RealSense recording also gives the header its ``camera`` (the colour intrinsics) and, when it has depth,
each frame its ``depth_m`` (the aligned depth at the landmarks, ``landmarks.with_depth``) and the header its
``"depth": {"source": "realsense", "aligned_to": "color"}``; when it has an accelerometer stream (D435i,
D455, or ``posed record``), each frame its ``gravity`` (hal.imu); the other inputs write none of these.

Several people (up to ``landmarks.max_people``, :class:`landmarks.MultiPoseLandmarker`): each frame's
``landmarks`` are those of the person followed longest; from the first frame with two people on, every frame
also carries ``people`` with each person's track id. With one person in view the output is what it was.

Frame times: a video's or RealSense recording's own frame timestamps (seconds from its first frame); images:
``seq / fps``. A frame that cannot be decoded is reported on stderr and left out (its ``seq`` is skipped, so
the gap shows); the rest is still written. So is an image larger than ``hal.MAX_DECODE_PIXELS`` (its size read
from its header, never decoded). An output that is the input (or one of the folder's images) is refused before
anything is written. Exit status: 0 all frames read, 1 some frames could not be read, 2 nothing could be done
(input or models missing, the output is the input or cannot be created), 74 writing the recording failed (a
full disk: the partial file is removed).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from posed.camera_model import Intrinsics
from posed.commands import add_config_args, bounded_float, config_from_args, error_printer
from posed.commands._paths import Output, OutputError, config_inputs, refuse_same_file

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm"}
READ_TIMEOUT_S = 5.0        # a RealSense recording's next frame (played as fast as it decodes)
MAX_FPS = 1000.0            # --fps: above this it is a typo, not a camera


class InputError(Exception):
    """The input cannot be read at all."""


@dataclass(frozen=True)
class InputFrame:
    """One input frame; ``t`` seconds from the first frame, kept to the microsecond (as the HAL's sidecar
    does): ``seq / fps`` in binary floating point writes 0.6000000000000001 for 0.6."""

    seq: int
    t: float
    image: np.ndarray | None  # None: this frame could not be read
    problem: str = ""
    depth: np.ndarray | None = None   # H x W uint16 aligned to the image, 0 = none
    depth_scale: float = 0.0          # metres per depth unit
    gravity: tuple[float, float, float] | None = None   # down, colour camera axes (hal.Frame.gravity)

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", round(self.t, 6))


@dataclass
class FrameSource:
    kind: str           # "image", "video", "folder" or "realsense"
    fps: float
    image_size: tuple[int, int]
    frames: Iterator[InputFrame]
    camera: Intrinsics | None = None  # of the image, when the input knows it
    has_depth: bool = False           # the frames come with aligned depth
    total: int = 0                    # frames expected (a video's frame count, a folder's files); 0 unknown


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("landmarks", help="run the 2D landmark stage on an image, video, folder of images "
                                              "or RealSense recording")
    parser.add_argument("input", metavar="INPUT", help="an image, a video file, a folder of images or a RealSense "
                                                       "recording (.db3/.bag; its depth is sampled at the "
                                                       "landmarks)")
    parser.add_argument("-o", "--output", metavar="OUT.landmarks.jsonl", default="-",
                        help="landmark recording to write (default: standard output)")
    parser.add_argument("--mode", choices=("video", "image"), default=None,
                        help="video: track across frames (MediaPipe's video mode; default for videos and "
                             "folders); image: every frame on its own (detector every frame, no smoothing)")
    parser.add_argument("--fps", type=bounded_float(0.0, MAX_FPS, "frames per second"), default=None,
                        help="frame rate for images and folders (t = seq / fps; more than 0, at most "
                             f"{MAX_FPS:g}); default: the video's own, else source.fps")
    add_config_args(parser, source=False, example="landmarks.threads=2")
    parser.set_defaults(func=run)


_err = error_printer("posed landmarks")


def _image_size(path: Path) -> tuple[tuple[int, int] | None, str]:
    """((width, height) or None, why not) from the file's header, without decoding it: hal's image replay
    checks a frame's size against ``Source.max_pixels`` on the header before it decodes anything, so with a
    limit of one pixel it reports the size of every image and decodes none."""
    from posed import hal

    source = hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False))
    source.max_pixels = 1
    try:
        source.open()
        source.read(READ_TIMEOUT_S)
    except hal.SourceCorrupt as exc:
        if exc.pixels is None:
            return None, str(exc)
        m = re.search(r"(\d+)x(\d+) image", str(exc))
        return ((int(m.group(1)), int(m.group(2))) if m else (exc.pixels, 1)), ""
    except hal.SourceError as exc:
        return None, str(exc)
    finally:
        source.close()
    return (1, 1), ""          # a one-pixel image: within the limit


def _read_image(path: Path) -> tuple[np.ndarray | None, str]:
    """The image (BGR), or None and why it cannot be read. An image larger than ``hal.MAX_DECODE_PIXELS`` (its
    size read from its header) is never decoded: a crafted header must not make the decoder allocate gigabytes."""
    from posed import hal

    if not path.is_file():
        return None, f"{path}: cannot decode the image (corrupt or not an image)"
    size, _why = _image_size(path)
    if size is not None and size[0] * size[1] > hal.MAX_DECODE_PIXELS:
        return None, (f"{path}: image too large: {size[0]} x {size[1]}, at most {hal.MAX_DECODE_PIXELS} pixels "
                      "(7680 x 4320); scale it down; left out")
    data = np.fromfile(str(path), dtype=np.uint8)
    if data.size == 0:
        return None, f"{path}: cannot decode the image (empty file)"
    try:
        image = cv2.imdecode(data, cv2.IMREAD_COLOR)
    except cv2.error:            # OpenCV's own size limit, for a header hal could not read
        image = None
    if image is None:
        return None, f"{path}: cannot decode the image (corrupt or not an image)"
    return image, ""


def open_input(path: Path, fps: float | None, default_fps: float) -> FrameSource:
    """The frames of an image, a video or a folder of images (InputError when there are none to read)."""
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise InputError(f"{path}: the folder holds no images ({', '.join(sorted(IMAGE_SUFFIXES))})")
        return _image_files(files, "folder", fps or default_fps)
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return _image_files([path], "image", fps or default_fps)
    from posed import hal

    if hal.is_realsense_recording(path):
        return _realsense(path, fps, default_fps)
    return _video(path, fps, default_fps)


def _image_files(files: list[Path], kind: str, fps: float) -> FrameSource:
    first, why = None, ""
    for f in files:
        first, why = _read_image(f)
        if first is not None:
            break
    if first is None:
        if len(files) == 1:
            raise InputError(why)
        raise InputError(f"{files[0].parent} ({len(files)} files): cannot decode any image (corrupt, too large or "
                         "not images)")
    size = (first.shape[1], first.shape[0])

    def frames() -> Iterator[InputFrame]:
        for seq, f in enumerate(files):
            image, why = _read_image(f)
            t = seq / fps
            if image is None:
                yield InputFrame(seq, t, None, why)
            elif (image.shape[1], image.shape[0]) != size:
                yield InputFrame(seq, t, None, f"{f}: image is {image.shape[1]}x{image.shape[0]}, the "
                                               f"recording is {size[0]}x{size[1]}; left out")
            else:
                yield InputFrame(seq, t, image)

    return FrameSource(kind, fps, size, frames(), total=len(files))


def _video(path: Path, fps: float | None, default_fps: float) -> FrameSource:
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise InputError(f"{path}: cannot open as a video or image (unknown format or corrupt file)")
    ok, first = cap.read()
    if not ok or first is None:
        cap.release()
        raise InputError(f"{path}: the video holds no decodable frame (corrupt or empty)")
    video_fps = cap.get(cv2.CAP_PROP_FPS)
    rate = fps or (video_fps if math.isfinite(video_fps) and video_fps > 0 else default_fps)
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    size = (first.shape[1], first.shape[0])

    def frames() -> Iterator[InputFrame]:
        seq, image, t0, last_t = 0, first, None, -math.inf
        try:
            while True:
                msec = cap.get(cv2.CAP_PROP_POS_MSEC)
                t_file = msec / 1000.0 if math.isfinite(msec) else math.nan
                if fps is None and math.isfinite(t_file):
                    t0 = t_file if t0 is None else t0
                    t = t_file - t0
                    t = t if t > last_t else seq / rate  # broken timestamps: fall back to seq / fps
                else:
                    t = seq / rate
                last_t = t
                yield InputFrame(seq, t, image)
                seq += 1
                ok, image = cap.read()
                if not ok or image is None:
                    break
            if count > 0 and seq < count - 1:
                yield InputFrame(seq, seq / rate, None,
                                 f"{path}: the video ended after {seq} of {count} frames (truncated or corrupt)")
        finally:
            cap.release()

    return FrameSource("video", rate, size, frames(), total=max(count, 0))


def _realsense(path: Path, fps: float | None, default_fps: float) -> FrameSource:
    """A RealSense recording played as fast as it decodes, colour with its aligned depth (hal)."""
    from posed import hal

    source = None
    try:
        source = hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False))
        source.open()
        first = source.read(READ_TIMEOUT_S)
    except hal.SourceError as exc:
        if source is not None:
            source.close()
        if isinstance(exc, hal.EndOfStream):
            raise InputError(f"{path}: the RealSense recording holds no frame") from None
        raise InputError(str(exc)) from None
    recorded_fps = float(source.info.get("fps") or 0.0)
    rate = fps or (recorded_fps if math.isfinite(recorded_fps) and recorded_fps > 0 else default_fps)

    def frames() -> Iterator[InputFrame]:
        frame, n = first, 0
        try:
            while True:
                t = frame.t - first.t if fps is None else n / rate
                yield InputFrame(frame.seq, t, frame.image, depth=frame.depth, depth_scale=frame.depth_scale,
                                 gravity=frame.gravity)
                n += 1
                try:
                    frame = source.read(READ_TIMEOUT_S)
                except hal.EndOfStream:
                    break
                except hal.SourceError as exc:
                    yield InputFrame(frame.seq + 1, n / rate, None, f"{path}: reading stopped after {n} "
                                                                     f"frame(s): {exc}")
                    break
        finally:
            source.close()

    return FrameSource("realsense", rate, (first.width, first.height), frames(), camera=first.intrinsics,
                       has_depth=first.depth is not None)


class Progress:
    """A progress line on stderr every ``period_s`` (rewritten in place on a terminal); none for one image."""

    def __init__(self, total: int, period_s: float = 2.0) -> None:
        self.total, self.period_s = total, period_s
        self.t0 = time.monotonic()
        self.next = self.t0 + period_s
        self.tty = sys.stderr.isatty()
        self.shown = False

    def frame(self, done: int, found: int) -> None:
        now = time.monotonic()
        if now < self.next or (self.total == 1):
            return
        self.next = now + self.period_s
        rate = done / max(now - self.t0, 1e-9)
        of = f"/{self.total} ({100.0 * done / self.total:.0f} %)" if self.total else ""
        left = f", about {(self.total - done) / rate:.0f} s left" if self.total and rate > 0 else ""
        line = f"posed landmarks: frame {done}{of}, {rate:.1f} frames/s, person in {found}{left}"
        print(("\r" + line + "\033[K") if self.tty else line, end="" if self.tty else "\n", file=sys.stderr,
              flush=True)
        self.shown = True

    def end(self) -> None:
        if self.shown and self.tty:
            print(file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    from posed.landmarks import (
        DepthSource,
        ModelMissingError,
        MultiPoseLandmarker,
        RecordingHeader,
        dumps,
        with_depth,
    )

    path = Path(args.input)
    inputs = [("input", args.input), *config_inputs(args)]
    if path.is_dir():
        inputs += [("image in the input folder", str(p)) for p in path.iterdir()]
    refused = refuse_same_file("posed landmarks", args.output, inputs)
    if refused is not None:
        return refused
    config = config_from_args(args)
    try:
        source = open_input(path, args.fps, config.source.fps)
    except InputError as exc:
        _err(str(exc))
        return 2
    mode = args.mode or ("image" if source.kind == "image" else "video")
    lm_config = replace(config.landmarks, tracking=(mode == "video"))
    try:
        landmarker = MultiPoseLandmarker(lm_config)
    except ModelMissingError as exc:  # also ModelCorruptError
        _err(str(exc))
        return 2

    header = RecordingHeader(source.image_size, source.fps, source=f"posed landmarks {path.name} ({mode} mode)",
                             camera=source.camera, depth=DepthSource("realsense", "color") if source.has_depth
                             else None, extra={"sides_kept": lm_config.keep_sides})
    problems = written = found = most = 0
    progress = Progress(source.total if source.kind != "image" else 0)
    out = Output("posed landmarks", args.output)
    try:
        out.open()
    except OSError as exc:
        return out.open_failed(exc)
    try:
        out.write(dumps(header.to_json()) + "\n")
        for frame in source.frames:
            if frame.image is None:
                _err(frame.problem)
                problems += 1
                continue
            result = with_depth(landmarker.process(frame.image, frame.t, frame.seq), frame.depth,
                                frame.depth_scale)
            if frame.gravity is not None:
                result = replace(result, gravity=frame.gravity)
            out.write(dumps(result.to_json()) + "\n")
            out.flush()
            written += 1
            found += result.landmarks is not None
            most = max(most, len(result.people or ()))
            progress.frame(written + problems, found)
        out.close()
    except OutputError as exc:
        progress.end()
        return out.failed(exc.exc)
    finally:
        out.discard()
    progress.end()
    summary = f"{written} frame(s), person found in {found}"
    if most > 1:
        summary += f", up to {most} people at once (frames carry 'people')"
    if problems:
        summary += f", {problems} problem(s) reported above"
    _err(summary + ("" if args.output == "-" else f" -> {args.output}"))
    return 1 if problems else 0
