"""Configuration of the camera source (config section ``source``).

A source URI (``realsense:SERIAL``, ``v4l2:/dev/video0``, ``file:PATH?drop=0.1&loop=true``) is another way to
write these keys: see :mod:`hal.uri` and docs/hal.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

SOURCE_TYPES = ("realsense", "v4l2", "file")
INFRARED_MODES = ("auto", "off", "always")   # source.infrared (hal.night)

NEVER = -1  # a fault_*_at value that never fires


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
    fps: float = field(default=30.0, metadata={"doc": "capture rate (image folders without timestamps: "
                                                      "replay rate)", "unit": "Hz", "range": (1.0, 120.0)})
    realtime: bool = field(
        default=True, metadata={"doc": "file: pace frames by their recorded timestamps (false = as fast as taken)"}
    )
    loop: bool = field(default=False, metadata={"doc": "file: start again at the end"})
    read_timeout_s: float = field(
        default=2.0, metadata={"doc": "longest wait for one frame", "unit": "s", "range": (0.05, 60.0)}
    )
    depth: bool = field(default=True, metadata={"doc": "realsense: also stream depth, aligned to colour"})
    imu: bool = field(default=True, metadata={
        "doc": "realsense: read the accelerometer (D435i, D455; a recording's accel stream) for the direction of "
               "gravity, which falls.imu_gravity uses instead of the camera tilt and roll; cameras without one "
               "(D435, D415) stream as before"})
    infrared: str = field(default="auto", metadata={
        "doc": "realsense (live and recordings): also stream the left infrared imager and deliver its image when "
               "the colour image is dark (auto: below a mean luma, with hysteresis; hal.night), always, or "
               "never (off); other sources ignore it", "choices": INFRARED_MODES})
    fx: float = field(default=0.0, metadata={
        "doc": "v4l2/file: focal length x at width x height; 0 = unknown (frames carry no intrinsics)",
        "unit": "px", "range": (0.0, 100000.0)})
    fy: float = field(default=0.0, metadata={"doc": "v4l2/file: focal length y; 0 = same as fx", "unit": "px",
                                             "range": (0.0, 100000.0)})
    cx: float = field(default=0.0, metadata={"doc": "v4l2/file: principal point x; 0 = image centre",
                                             "unit": "px", "range": (0.0, 100000.0)})
    cy: float = field(default=0.0, metadata={"doc": "v4l2/file: principal point y; 0 = image centre",
                                             "unit": "px", "range": (0.0, 100000.0)})
    mjpg: bool = field(default=True, metadata={"doc": "v4l2: ask the camera for MJPG (needed for 640x480@30 and "
                                                      "more on USB 2)"})
    buffer_size: int = field(default=1, metadata={"doc": "v4l2: driver frame buffers (1 = always the newest)",
                                                  "range": (1, 10)})
    timeouts_before_reopen: int = field(default=3, metadata={
        "doc": "realsense/v4l2: consecutive read timeouts after which the camera is closed and opened again",
        "range": (1, 1000)})
    failures_before_reset: int = field(default=3, metadata={
        "doc": "realsense: failed re-opens in a row after which the camera gets a hardware reset",
        "range": (1, 1000)})
    reconnect_initial_s: float = field(default=0.5, metadata={
        "doc": "realsense/v4l2: first wait before reconnecting an unplugged camera (doubles each failure)",
        "unit": "s", "range": (0.001, 60.0)})
    reconnect_max_s: float = field(default=10.0, metadata={
        "doc": "realsense/v4l2: longest wait between reconnect attempts", "unit": "s", "range": (0.01, 600.0)})
    fault_drop: float = field(default=0.0, metadata={
        "doc": "test fault: probability that a frame is silently dropped (URI ?drop=)", "range": (0.0, 1.0)})
    fault_stall_at: int = field(default=NEVER, metadata={
        "doc": "test fault: at this frame the source sends nothing for fault_stall_s (-1 = never; ?stall_at=)",
        "range": (-1, None)})
    fault_stall_s: float = field(default=3.0, metadata={
        "doc": "test fault: length of the stall (?stall_s=)", "unit": "s", "range": (0.0, 3600.0)})
    fault_disconnect_at: int = field(default=NEVER, metadata={
        "doc": "test fault: at this frame the source is unplugged for fault_disconnect_s (-1 = never; "
               "?disconnect_at=)", "range": (-1, None)})
    fault_disconnect_s: float = field(default=2.0, metadata={
        "doc": "test fault: how long the source stays unplugged; 0 = until closed (?disconnect_s=)",
        "unit": "s", "range": (0.0, 3600.0)})
    fault_corrupt_at: int = field(default=NEVER, metadata={
        "doc": "test fault: this frame cannot be decoded (SourceCorrupt; -1 = never; ?corrupt_at=)",
        "range": (-1, None)})
    fault_seed: int = field(default=0, metadata={"doc": "test fault: seed of the frame dropping (?seed=)",
                                                 "range": (0, None)})

    def __post_init__(self) -> None:
        if self.reconnect_max_s < self.reconnect_initial_s:
            raise ValueError(f"reconnect_max_s: {self.reconnect_max_s} is below reconnect_initial_s "
                             f"({self.reconnect_initial_s}); the wait between reopening tries doubles from "
                             "reconnect_initial_s up to reconnect_max_s: raise reconnect_max_s or lower "
                             "reconnect_initial_s")

    @property
    def has_faults(self) -> bool:
        """True when any test fault is configured."""
        return (self.fault_drop > 0.0 or self.fault_stall_at >= 0 or self.fault_disconnect_at >= 0
                or self.fault_corrupt_at >= 0)
