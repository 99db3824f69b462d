"""``open_source(spec)``: a source from a config or URI, through an explicit registry of source kinds.

``REGISTRY`` maps ``source.type`` to a factory ``(SourceConfig) -> Source``; :func:`register` adds one.
The RealSense module (and pyrealsense2) is imported only when a RealSense source is asked for.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceNotFound, SourceUnsupported
from posed.hal.source import Source
from posed.hal.uri import parse_uri, split_query

VIDEO_EXTENSIONS = (".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm", ".mpg", ".mpeg", ".ts", ".wmv", ".flv",
                    ".h264", ".h265", ".mjpeg", ".mjpg", ".gif", ".3gp")
REALSENSE_EXTENSIONS = (".db3", ".bag")
LANDMARKS_SUFFIX = ".landmarks.jsonl"

SourceFactory = Callable[[SourceConfig], Source]


def is_landmark_recording(path: str | os.PathLike) -> bool:
    """True for a ``*.landmarks.jsonl`` recording, which the daemon replays itself (no camera stage)."""
    return str(path).lower().endswith(LANDMARKS_SUFFIX)


def is_realsense_recording(path: str | os.PathLike) -> bool:
    """True for a RealSense recording (``.db3`` or ``.bag``, any case), which carries depth."""
    return Path(path).suffix.lower() in REALSENSE_EXTENSIONS


def _open_realsense(config: SourceConfig) -> Source:
    from posed.hal.realsense import RealSenseSource

    return RealSenseSource(config)


def _open_v4l2(config: SourceConfig) -> Source:
    from posed.hal.v4l2 import V4L2Source

    return V4L2Source(config)


def open_file(config: SourceConfig) -> Source:
    """The replay source for ``config.path``: a video, an image folder or image, or a RealSense recording."""
    path = config.path
    if not path:
        raise SourceNotFound("file: source without a path; set source.path or use --source file:PATH (the "
                             "daemon substitutes its demo input for an empty path)", "file:")
    if is_landmark_recording(path):
        raise SourceUnsupported(
            f"{path} is a landmark recording: the daemon replays it directly and skips the camera and landmark "
            "stages (landmarks.recording); hal opens only videos, image folders and RealSense recordings",
            f"file:{path}")
    p = Path(path)
    if not p.exists():
        raise SourceNotFound(f"{path}: no such file or folder; check source.path or the file: URI", f"file:{path}")
    suffix = p.suffix.lower()
    if p.is_dir():
        from posed.hal.images import ImageFolderSource

        return ImageFolderSource(config, path)
    if is_realsense_recording(p):
        from posed.hal.realsense import RealSenseSource

        return RealSenseSource(config, playback=path)
    from posed.hal.images import IMAGE_EXTENSIONS, ImageFolderSource

    if suffix in IMAGE_EXTENSIONS:
        return ImageFolderSource(config, path)
    from posed.hal.video import VideoFileSource

    if suffix in VIDEO_EXTENSIONS:
        return VideoFileSource(config, path)
    return _probe_unknown_file(config, path)


def file_problem(path: str | os.PathLike) -> str | None:
    """Why hal could not open the existing file ``path`` as a source (None: it can), checked before anything
    starts: a known extension is trusted; another file must open as a video. A landmark recording under another
    name is recognised by its header and told to take the suffix."""
    p = Path(path)
    if not p.is_file() or is_landmark_recording(p) or is_realsense_recording(p):
        return None
    from posed.hal.images import IMAGE_EXTENSIONS

    if p.suffix.lower() in IMAGE_EXTENSIONS + VIDEO_EXTENSIONS:
        return None
    try:
        with open(p, "rb") as fh:
            head = fh.read(256)
    except OSError as exc:
        return f"{p} cannot be read ({exc.strerror or exc})"
    if head.lstrip().startswith(b"{") and b'"posed.landmarks"' in head:
        return (f"{p} is a landmark recording without the {LANDMARKS_SUFFIX} suffix: rename it to "
                f"{p.with_suffix('').name}{LANDMARKS_SUFFIX} (the daemon replays landmark recordings by that name)")
    import cv2

    cap = cv2.VideoCapture(str(p), cv2.CAP_FFMPEG)
    ok = cap.isOpened()
    cap.release()
    if not ok:
        return (f"{p}: not a video, image, image folder, RealSense recording (.db3/.bag) or landmark recording "
                f"({LANDMARKS_SUFFIX}) that posed can read; videos: {' '.join(VIDEO_EXTENSIONS)}")
    return None


def _probe_unknown_file(config: SourceConfig, path: str) -> Source:
    """A file with an unknown extension: accepted only when OpenCV can open it as a video."""
    import cv2

    cap = cv2.VideoCapture(path, cv2.CAP_FFMPEG)
    ok = cap.isOpened()
    cap.release()
    if not ok:
        raise SourceUnsupported(
            f"{path}: not a video, image, image folder or RealSense recording (.db3/.bag) that hal can read; "
            f"videos: {' '.join(VIDEO_EXTENSIONS)}", f"file:{path}")
    from posed.hal.video import VideoFileSource

    return VideoFileSource(config, path)


REGISTRY: dict[str, SourceFactory] = {
    "realsense": _open_realsense,
    "v4l2": _open_v4l2,
    "file": open_file,
}


def register(kind: str, factory: SourceFactory) -> None:
    """Add (or replace) a source kind."""
    REGISTRY[kind] = factory


def open_source(spec: SourceConfig | str) -> Source:
    """A source (not yet opened) for a ``SourceConfig`` or a URI string.

    Raises SourceUnsupported for an unknown kind, bad URI or landmark recording, SourceNotFound for a path
    that does not exist; ``open()`` on the result raises the rest. Test faults (``fault_*`` keys or URI query)
    wrap the source in :class:`hal.faults.FaultySource`.
    """
    config = parse_uri(spec) if isinstance(spec, str) else split_query(spec)
    factory = REGISTRY.get(config.type)
    if factory is None:
        raise SourceUnsupported(f"source type {config.type!r} is not one of: {', '.join(REGISTRY)}", config.type)
    source = factory(config)
    if config.has_faults:
        from posed.hal.faults import FaultySource

        source = FaultySource(source, config)
    return source
