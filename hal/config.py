"""Configuration of the camera source (config section ``source``)."""

from __future__ import annotations

from dataclasses import dataclass, field

SOURCE_TYPES = ("realsense", "v4l2", "file")


@dataclass(frozen=True)
class SourceConfig:
    """Which camera (or recording) the capture stage reads, and how."""

    type: str = field(default="file", metadata={"doc": "kind of source", "choices": SOURCE_TYPES})
    path: str = field(
        default="",
        metadata={"doc": "file: a video, a folder of images, a RealSense .db3/.bag, or a .landmarks.jsonl; "
                         "empty = the embedded demo input"},
    )
    device: str = field(default="/dev/video0", metadata={"doc": "v4l2: device path or index"})
    serial: str = field(default="", metadata={"doc": "realsense: serial number; empty = first device"})
    width: int = field(default=640, metadata={"doc": "capture width", "unit": "px", "range": (160, 4096)})
    height: int = field(default=480, metadata={"doc": "capture height", "unit": "px", "range": (120, 4096)})
    fps: float = field(default=30.0, metadata={"doc": "capture rate", "unit": "Hz", "range": (1.0, 120.0)})
    realtime: bool = field(
        default=True, metadata={"doc": "file: pace frames by their recorded timestamps (false = as fast as taken)"}
    )
    loop: bool = field(default=False, metadata={"doc": "file: start again at the end"})
    read_timeout_s: float = field(
        default=2.0, metadata={"doc": "longest wait for one frame", "unit": "s", "range": (0.05, 60.0)}
    )
