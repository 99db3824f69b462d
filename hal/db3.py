"""Writing RealSense recordings (ROS 2 ``.db3``, what librealsense 2.59 records) from frames, with
pyrealsense2's software device and recorder; the RealSense source plays them back like a camera.

Colour is stored as bgr8 and depth as z16, both losslessly (checked bit-exact by the tests). Timestamps are
the frames' capture times in milliseconds from the first frame, domain ``hardware_clock``; frame numbers are
the frames' ``seq``, so a replay shows the same numbers and gaps.

Depth may have its own intrinsics and an extrinsic transform to colour (a raw depth stream, as a camera
delivers it); ``posed record`` writes depth already aligned to colour (same intrinsics, identity transform).
An accelerometer stream (``accel_fps``) holds motion frames in the depth sensor's axes, m/s^2, as a D435i's
(:mod:`hal.imu`); ``posed record`` writes one sample per frame that carried gravity, the opposite of the
frame's down vector times g (the low-passed reading, not the raw samples). A gyro stream (``gyro_fps``) beside
it, on the same motion sensor, holds angular rates in rad/s in the same axes, as a D435i's gyro
(``write_gyro``); a recording without one plays as an accelerometer-only camera.

An infrared stream (``infrared``) holds the left infrared imager's images (stream index 1, y8, as a D4xx's
"Stereo Module" delivers them; ``write(..., infrared=Y8 image)``), at ``infrared_intrinsics`` (default the
colour's). The left imager is the frame depth is computed in, so its extrinsics are the identity to depth (and
through it depth's to colour), or, in a recording without depth, the identity to colour. Depth given the
infrared intrinsics thus lies on the infrared grid, as a camera's raw depth does.

Note: ``rs.extrinsics()`` starts with an all-zero rotation; an unset rotation makes alignment map all depth to
0, so the identity is always written explicitly.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from posed.camera_model import Intrinsics
from posed.hal.errors import SourceUnsupported
from posed.hal.realsense import import_rs
from posed.hal.rs_playback import INFRARED_INDEX

IDENTITY_ROTATION = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


class Db3Writer:
    """Record colour (+ depth) frames into a ``.db3`` RealSense recording.

    ``depth_scale`` None records colour only. ``depth_intrinsics`` default: the colour intrinsics (depth
    already aligned); ``depth_to_colour`` = (rotation 9 values row-major, translation 3 values in metres),
    default identity. ``accel_fps``: also record an accelerometer stream at this rate (``write_accel``);
    ``gyro_fps`` (with ``accel_fps``): a gyro stream too (``write_gyro``). ``infrared``: an infrared stream
    (index 1, y8) at ``infrared_intrinsics`` (default the colour's), identity extrinsics to depth (module doc);
    its images go with ``write(..., infrared=...)``.
    """

    def __init__(self, path: str | os.PathLike, intrinsics: Intrinsics, fps: float,
                 depth_scale: float | None = None, depth_intrinsics: Intrinsics | None = None,
                 depth_to_colour: tuple[tuple[float, ...], tuple[float, ...]] | None = None,
                 serial: str = "posed-recording", name: str = "posed recording",
                 accel_fps: int | None = None, gyro_fps: int | None = None, infrared: bool = False,
                 infrared_intrinsics: Intrinsics | None = None) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() != ".db3":
            raise SourceUnsupported(f"{self.path}: librealsense 2.59 records ROS 2 .db3 files only; name the "
                                    "output NAME.db3", str(self.path))
        if gyro_fps is not None and accel_fps is None:
            raise ValueError("a gyro stream needs the accelerometer's beside it: give accel_fps too")
        if infrared_intrinsics is not None and not infrared:
            raise ValueError("infrared_intrinsics without an infrared stream: give infrared=True too")
        rs = import_rs()
        self._rs = rs
        if self.path.exists():
            self.path.unlink()  # the recorder refuses to append
        self.intrinsics = intrinsics
        self.depth_intrinsics = depth_intrinsics or intrinsics
        self.infrared_intrinsics = (infrared_intrinsics or intrinsics) if infrared else None
        rate = max(1, int(round(fps)))
        dev = rs.software_device()
        dev.register_info(rs.camera_info.name, name)
        dev.register_info(rs.camera_info.serial_number, serial)
        self._depth_sensor = None
        self._depth_profile = None
        self._infrared_sensor = None
        self._infrared_profile = None
        if depth_scale is not None:
            ds = dev.add_sensor("Depth")
            self._depth_profile = ds.add_video_stream(
                _video_stream(rs, rs.stream.depth, 0, self.depth_intrinsics, rate, rs.format.z16, 2))
            ds.add_read_only_option(rs.option.depth_units, float(depth_scale))
            self._depth_sensor = ds
        if self.infrared_intrinsics is not None:   # the left imager: beside depth on one sensor, as on a D4xx
            irs = self._depth_sensor if self._depth_sensor is not None else dev.add_sensor("Stereo Module")
            self._infrared_profile = irs.add_video_stream(
                _video_stream(rs, rs.stream.infrared, 4, self.infrared_intrinsics, rate, rs.format.y8, 1,
                              index=INFRARED_INDEX))
            self._infrared_sensor = irs
        cs = dev.add_sensor("Color")
        self._colour_profile = cs.add_video_stream(
            _video_stream(rs, rs.stream.color, 1, intrinsics, rate, rs.format.bgr8, 3))
        self._colour_sensor = cs
        if self._depth_profile is not None:
            rotation, translation = depth_to_colour or (IDENTITY_ROTATION, (0.0, 0.0, 0.0))
            ext = rs.extrinsics()
            ext.rotation = [float(v) for v in rotation]
            ext.translation = [float(v) for v in translation]
            self._depth_profile.register_extrinsics_to(self._colour_profile, ext)
        if self._infrared_profile is not None:
            self._infrared_profile.register_extrinsics_to(
                self._depth_profile if self._depth_profile is not None else self._colour_profile, _identity(rs))
        self._accel_sensor = None
        self._accel_profile = None
        self._gyro_profile = None
        if accel_fps is not None:
            ms = dev.add_sensor("Motion Module")
            self._accel_profile = ms.add_motion_stream(_motion_stream(rs, rs.stream.accel, 2, accel_fps))
            if gyro_fps is not None:
                self._gyro_profile = ms.add_motion_stream(_motion_stream(rs, rs.stream.gyro, 3, gyro_fps))
            self._accel_sensor = ms
        self._device = dev
        self._recorder: Any = rs.recorder(str(self.path), dev)
        stereo = self._depth_sensor if self._depth_sensor is not None else self._infrared_sensor
        self._sensors = [s for s in (stereo, cs, self._accel_sensor) if s is not None]
        motion = [p for p in (self._accel_profile, self._gyro_profile) if p is not None]
        stereo_profiles = [p for p in (self._depth_profile, self._infrared_profile) if p is not None]
        for sensor, profiles in ((stereo, stereo_profiles), (cs, [self._colour_profile]),
                                 (self._accel_sensor, motion)):
            if sensor is not None:
                sensor.open(profiles)
                sensor.start(_ignore)
        self.depth_scale = depth_scale
        self.frames = 0
        self.infrared_frames = 0
        self.accel_samples = 0
        self.gyro_samples = 0

    def write(self, image: np.ndarray, depth: np.ndarray | None, t_ms: float, number: int,
              infrared: np.ndarray | None = None) -> None:
        """Add one colour image (BGR uint8, H x W x 3), its depth (uint16 on the depth grid, or None) and, in a
        recording with an infrared stream, its infrared image (Y8: uint8 H x W on the infrared grid, or None)."""
        w, h = self.intrinsics.width, self.intrinsics.height
        if image.shape != (h, w, 3) or image.dtype != np.uint8:
            raise ValueError(f"colour image must be {h}x{w}x3 uint8, got {image.shape} {image.dtype}")
        if infrared is not None:
            k = self.infrared_intrinsics
            if k is None:
                raise ValueError("this recording has no infrared stream: open the writer with infrared=True")
            if infrared.shape != (k.height, k.width) or infrared.dtype != np.uint8:
                raise ValueError(f"infrared image must be {k.height}x{k.width} uint8 (Y8), got {infrared.shape} "
                                 f"{infrared.dtype}")
            self._send(self._infrared_sensor, self._infrared_profile, infrared, 1, t_ms, number)
            self.infrared_frames += 1
        if depth is not None and self._depth_sensor is not None:
            dw, dh = self.depth_intrinsics.width, self.depth_intrinsics.height
            if depth.shape != (dh, dw) or depth.dtype != np.uint16:
                raise ValueError(f"depth must be {dh}x{dw} uint16, got {depth.shape} {depth.dtype}")
            self._send(self._depth_sensor, self._depth_profile, depth, 2, t_ms, number,
                       depth_units=float(self.depth_scale or 0.001))
        self._send(self._colour_sensor, self._colour_profile, image, 3, t_ms, number)
        self.frames += 1

    def write_accel(self, t_ms: float, xyz: tuple[float, float, float]) -> None:
        """Add one accelerometer sample (m/s^2, depth sensor axes: about (0, -9.8, 0) level and at rest),
        stamped ``t_ms`` on the frames' clock."""
        if self._accel_sensor is None:
            raise ValueError("this recording has no accelerometer stream: open the writer with accel_fps")
        self._send_motion(self._accel_profile, t_ms, xyz, self.accel_samples)
        self.accel_samples += 1

    def write_gyro(self, t_ms: float, xyz: tuple[float, float, float]) -> None:
        """Add one gyro sample (angular rate, rad/s, right-handed, depth sensor axes), stamped ``t_ms`` on the
        frames' clock."""
        if self._gyro_profile is None:
            raise ValueError("this recording has no gyro stream: open the writer with accel_fps and gyro_fps")
        self._send_motion(self._gyro_profile, t_ms, xyz, self.gyro_samples)
        self.gyro_samples += 1

    def _send_motion(self, profile: Any, t_ms: float, xyz: tuple[float, float, float], number: int) -> None:
        rs = self._rs
        v = rs.vector()
        v.x, v.y, v.z = (float(c) for c in xyz)
        f = rs.software_motion_frame()
        f.data = v
        f.timestamp = float(t_ms)
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = int(number)
        f.profile = profile.as_motion_stream_profile()
        self._accel_sensor.on_motion_frame(f)

    def _send(self, sensor: Any, profile: Any, pixels: np.ndarray, bpp: int, t_ms: float, number: int,
              depth_units: float | None = None) -> None:
        """Hand one image (``bpp`` bytes per pixel, of the size of ``profile``) to a software sensor, stamped
        ``t_ms`` milliseconds (hardware clock) and frame ``number``; depth frames carry ``depth_units`` (m)."""
        rs = self._rs
        f = rs.software_video_frame()
        f.pixels = np.ascontiguousarray(pixels)
        f.bpp = bpp
        f.stride = pixels.shape[1] * bpp
        f.timestamp = float(t_ms)
        f.domain = rs.timestamp_domain.hardware_clock
        f.frame_number = int(number)
        f.profile = profile.as_video_stream_profile()
        if depth_units is not None:
            f.depth_units = depth_units
        sensor.on_video_frame(f)

    def close(self) -> None:
        """Stop the sensors and finish the file (the recorder writes its index when released)."""
        if self._recorder is None:
            return
        for sensor in self._sensors:
            try:
                sensor.stop()
                sensor.close()
            except RuntimeError:
                pass
        self._recorder = None
        self._sensors = []
        self._device = None

    def __enter__(self) -> Db3Writer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _ignore(_frame: Any) -> None:
    """Sensor callback: the recorder taps the frames; nothing else needs them."""


def _motion_stream(rs: Any, kind: Any, uid: int, fps: int) -> Any:
    m = rs.motion_stream()
    m.type, m.index, m.uid = kind, 0, uid
    m.fps, m.fmt = max(1, int(fps)), rs.format.motion_xyz32f
    m.intrinsics = rs.motion_device_intrinsic()
    return m


def _identity(rs: Any) -> Any:
    ext = rs.extrinsics()
    ext.rotation = list(IDENTITY_ROTATION)
    ext.translation = [0.0, 0.0, 0.0]
    return ext


def _video_stream(rs: Any, kind: Any, uid: int, k: Intrinsics, fps: int, fmt: Any, bpp: int,
                  index: int = 0) -> Any:
    intr = rs.intrinsics()
    intr.width, intr.height = int(k.width), int(k.height)
    intr.fx, intr.fy, intr.ppx, intr.ppy = float(k.fx), float(k.fy), float(k.cx), float(k.cy)
    intr.model = rs.distortion.none
    intr.coeffs = [0.0] * 5
    vs = rs.video_stream()
    vs.type = kind
    vs.index = index
    vs.uid = uid
    vs.width, vs.height = int(k.width), int(k.height)
    vs.fps = fps
    vs.bpp = bpp
    vs.fmt = fmt
    vs.intrinsics = intr
    return vs
