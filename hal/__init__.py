"""Hardware abstraction: RealSense, V4L2 and replay cameras behind one interface.

    from posed import hal
    with hal.open_source("file:squat.mp4?realtime=false") as src:   # or a hal.SourceConfig
        frame = src.read(timeout_s=2.0)                               # a hal.Frame

Sources: ``realsense:[SERIAL]`` (pyrealsense2, imported only then), ``v4l2:/dev/videoN`` (OpenCV),
``file:PATH`` (video, image folder or image, RealSense .db3/.bag). Errors derive from ``hal.SourceError``.
Other packages import only the names of ``__all__`` from ``hal`` itself: sources (``open_source``,
``register``, ``REGISTRY``, ``Source``, ``Frame``), URIs (``parse_uri``, ``to_uri``, ``SourceConfig``,
``is_landmark_recording``, ``is_realsense_recording``), recording (``record``, ``check_output``,
``RecordSummary``, ``Db3Writer``, loaded on first use), frame sizes (``scale_factor``, ``working_size``,
``downscale``, ``downscale_depth``, ``MAX_DECODE_PIXELS``: the capture stage's one downscale), the replay
clock (``ReplayClock``), the accelerometer's gravity filter (``GravityEstimate``, ``G_M_S2``: a benchmark
runs a moving head's samples through it) and the errors.
docs/hal.md describes timestamps, recovery, fault injection and recording.
"""

from typing import TYPE_CHECKING

from posed.hal.clock import ReplayClock
from posed.hal.config import SourceConfig
from posed.hal.errors import (
    EndOfStream,
    SourceCorrupt,
    SourceDisconnected,
    SourceError,
    SourceNotFound,
    SourceTimeout,
    SourceUnsupported,
)
from posed.hal.frame import Frame
from posed.hal.imu import G_M_S2, GravityEstimate
from posed.hal.night import mean_luma
from posed.hal.recorder import RecordSummary, check_output, record
from posed.hal.registry import (
    REGISTRY,
    file_problem,
    is_landmark_recording,
    is_realsense_recording,
    open_source,
    register,
)
from posed.hal.resize import MAX_DECODE_PIXELS, downscale, downscale_depth, scale_factor, working_size
from posed.hal.source import Source
from posed.hal.uri import parse_uri, to_uri

if TYPE_CHECKING:
    from posed.hal.db3 import Db3Writer

__all__ = [
    "G_M_S2",
    "GravityEstimate",
    "MAX_DECODE_PIXELS",
    "REGISTRY",
    "file_problem",
    "Db3Writer",
    "EndOfStream",
    "Frame",
    "RecordSummary",
    "ReplayClock",
    "Source",
    "SourceConfig",
    "SourceCorrupt",
    "SourceDisconnected",
    "SourceError",
    "SourceNotFound",
    "SourceTimeout",
    "SourceUnsupported",
    "check_output",
    "downscale",
    "downscale_depth",
    "is_landmark_recording",
    "is_realsense_recording",
    "mean_luma",
    "open_source",
    "parse_uri",
    "record",
    "register",
    "scale_factor",
    "to_uri",
    "working_size",
]


def __getattr__(name: str):
    # The RealSense recording writer loads on first use: only recording and the benchmarks need it, and its
    # module (with the RealSense glue) would add ~20 ms to every ``import hal``.
    if name == "Db3Writer":
        from posed.hal.db3 import Db3Writer

        globals()[name] = Db3Writer
        return Db3Writer
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
