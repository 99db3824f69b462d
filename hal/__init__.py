"""Hardware abstraction: RealSense, V4L2 and replay cameras behind one interface.

    import hal
    with hal.open_source("file:squat.mp4?realtime=false") as src:   # or a hal.config.SourceConfig
        frame = src.read(timeout_s=2.0)                               # hal.frame.Frame

Sources: ``realsense:[SERIAL]`` (pyrealsense2, imported only then), ``v4l2:/dev/videoN`` (OpenCV),
``file:PATH`` (video, image folder or image, RealSense .db3/.bag). Errors: :mod:`hal.errors`.
docs/hal.md describes timestamps, recovery, fault injection and recording.
"""

from hal.config import SourceConfig
from hal.errors import (
    EndOfStream,
    SourceCorrupt,
    SourceDisconnected,
    SourceError,
    SourceNotFound,
    SourceTimeout,
    SourceUnsupported,
)
from hal.frame import Frame, Intrinsics
from hal.recorder import RecordSummary, record
from hal.registry import REGISTRY, is_landmark_recording, open_source, register
from hal.source import Source
from hal.uri import parse_uri

__all__ = [
    "REGISTRY",
    "EndOfStream",
    "Frame",
    "Intrinsics",
    "RecordSummary",
    "Source",
    "SourceConfig",
    "SourceCorrupt",
    "SourceDisconnected",
    "SourceError",
    "SourceNotFound",
    "SourceTimeout",
    "SourceUnsupported",
    "is_landmark_recording",
    "open_source",
    "parse_uri",
    "record",
    "register",
]
