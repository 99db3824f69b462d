"""Intel RealSense colour + depth through pyrealsense2, live or from a recording (.db3, .bag).

pyrealsense2 is imported only here, and only when a RealSense source is opened, so the daemon runs without
it on other sources. A live camera streams through ``rs.pipeline`` (its one-frameset queue keeps only the
newest frame: live, the newest frame wins); a recording plays through :class:`hal.rs_playback.PlaybackPipeline`,
which reads the recorded sensors directly and loses no frame however slow the reader is. Both then share one
code path (``try_wait_for_frames`` + ``rs.align``); the clock mapping and the end of the stream differ.

Per frame: the colour image (BGR), depth aligned to colour by ``rs.align(rs.stream.color)`` (uint16, units of
``depth_scale`` metres, from the depth sensor), the colour intrinsics (valid for the aligned depth too), and
with ``source.imu`` on a camera or recording that has an accelerometer (D435i, D455) the direction of gravity
(:mod:`hal.imu`: low-passed samples stamped up to the colour frame's time, turned into the colour camera's
axes by the depth -> colour rotation; with the motion sensor's gyro, when it has one, turned with the camera
between them). Live, the motion sensor is opened on its own beside the pipeline, so its 63-250 accelerometer
and 200-400 gyro samples per second never crowd colour framesets out of the pipeline's one-frameset queue.
Playback delivers every colour frame of the recording exactly once, with the depth frame recorded with it;
frame numbers not above the last one delivered are skipped (a playback re-opened after a stall starts the
file again) and counted as ``duplicates``. Live, a frameset repeating the last colour frame is skipped too.

Night (``source.infrared``, :mod:`hal.night`): unless ``off``, the left infrared imager (stream index 1, y8, at
the colour's size and rate) streams too, live or from a recording that has it. Per frame the chooser picks the
colour image or, in a dark room (or a blank colour frame), the infrared one; an infrared frame carries that
imager's grey image as BGR, its intrinsics, the raw depth when depth lies on its grid (same intrinsics,
identity extrinsics: a D4xx computes depth in that imager's frame) and gravity in its axes. Live, a camera that
cannot start with the infrared stream starts without it under ``auto`` (``info["infrared"]`` says the error).

Timestamps: live frames stamped on ``global_time``/``system_time`` (host clock, ms) are mapped from wall to
monotonic time; ``hardware_clock`` stamps go through :class:`hal.clock.DeviceClock`. Playback: ``t = t_start +
(ts - ts_first)`` as for every file (see :mod:`hal.replay`), paced by the recorded stamps when ``realtime``;
playback itself runs with ``set_real_time(False)`` and waits for the reader, so that no frame is skipped.

Recovery (live): each read that gets no frame within its timeout raises SourceTimeout and is counted; after
``timeouts_before_reopen`` in a row the pipeline is stopped and started again; if the camera is gone reads
raise SourceDisconnected while it is looked for with exponential backoff (``reconnect_initial_s`` doubling to
``reconnect_max_s``); after ``failures_before_reset`` failed starts in a row the camera gets a
``hardware_reset()`` (it drops off USB and comes back after a few seconds). A native hang or crash inside
librealsense cannot be caught here: run the capture in its own process (the daemon does) and watch it.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from posed.camera_model import Intrinsics
from posed.hal.blank import BLANK_FIX, blank_message, is_blank
from posed.hal.clock import DeviceClock, wall_to_monotonic
from posed.hal.config import SourceConfig
from posed.hal.errors import (
    EndOfStream,
    SourceCorrupt,
    SourceDisconnected,
    SourceNotFound,
    SourceUnsupported,
)
from posed.hal.frame import Frame
from posed.hal.imu import GravityEstimate, find_accel, find_gyro, rotation_of, sample_sink
from posed.hal.night import COLOUR, INFRARED, SpectrumChooser
from posed.hal.replay import Timeline
from posed.hal.rs_playback import INFRARED_INDEX, PlaybackPipeline
from posed.hal.source import Source

# After hardware_reset() the camera re-enumerates; touching it too soon has crashed librealsense
# (realsenseai/librealsense#11304), so the next start waits at least this long.
RESET_SETTLE_S = 5.0
# Playback waits for frames in slices this long, checking in between whether the file has ended.
PLAYBACK_SLICE_S = 0.05


def import_rs() -> Any:
    """The pyrealsense2 module, or SourceUnsupported saying how to get it."""
    try:
        import pyrealsense2 as rs
    except ImportError as exc:
        raise SourceUnsupported(
            f"pyrealsense2 cannot be imported ({exc}): install it (`pip install pyrealsense2`, x86_64 wheels; "
            "it needs the system library libusb-1.0-0) or use a v4l2: or file: source", "realsense:") from exc
    return rs


class RealSenseSource(Source):
    """A RealSense camera (``playback=None``) or a RealSense recording (played losslessly, see module doc).

    ``pipeline_factory`` is the seam for tests that script stalls around the real pipeline: live it is called
    with no argument and must return an ``rs.pipeline`` (default, or a subclass); for a recording it is called
    with the pyrealsense2 module and must return a :class:`PlaybackPipeline` (default, or a subclass).
    ``info`` adds serial, device name, size, fps, depth scale, intrinsics, ``imu`` and ``gyro`` (off | none |
    streaming | error: ...), ``infrared`` (off | none: no infrared stream | standby | in use | error: ...),
    ``spectrum`` (of the last frame: colour | infrared), ``infrared_intrinsics`` and the counters timeouts,
    reopens, reopen_failures, hardware_resets, disconnects, duplicates, passes, infrared_frames,
    spectrum_switches.
    """

    kind = "realsense"

    def __init__(self, config: SourceConfig, playback: str | None = None,
                 pipeline_factory: Callable[[], Any] | None = None, clock=time.monotonic, sleep=time.sleep) -> None:
        super().__init__(config, f"file:{playback}" if playback else f"realsense:{config.serial}")
        self.playback = playback
        self._pipeline_factory = pipeline_factory
        self._clock = clock
        self._sleep = sleep
        self._rs: Any = None
        self._pipe: Any = None
        self.serial = ""
        self.device_name = ""
        self.intrinsics: Intrinsics | None = None
        self.depth_scale = 0.0
        self.size = (0, 0)
        self.fps = 0.0
        self.colour_format = ""
        self.counters.update(timeouts=0, reopens=0, reopen_failures=0, hardware_resets=0, disconnects=0,
                             duplicates=0, passes=0, corrupt=0, blank=0, infrared_frames=0, spectrum_switches=0)
        self._gravity: GravityEstimate | None = None   # this start's accelerometer filter, when there is one
        self._imu_sensor: Any = None                   # live: the motion sensor opened beside the pipeline
        self.imu = "off" if not config.imu else "none"  # off | none (no accelerometer) | streaming | error: ...
        self.gyro = self.imu                            # off | none (no gyro: accelerometer only) | streaming | ...
        # ``infrared`` without a usable stream: off | none | error: ...
        self._infrared_unused = "off" if config.infrared == "off" else "none"
        self.spectrum = COLOUR                          # what the last frame delivered showed
        self._chooser = SpectrumChooser(config.infrared)
        self._infrared: _InfraredStream | None = None   # the usable infrared stream of this start, if any
        self._infrared_error = ""                       # live: why the camera streams without infrared
        self._infrared_asked = False                    # this start asked for the infrared stream

    # -- Source -------------------------------------------------------------------------------------------
    def _open(self) -> None:
        self._rs = import_rs()
        if self.playback is not None:
            if not os.path.isfile(self.playback):
                raise SourceNotFound(f"{self.playback}: no such RealSense recording; check source.path", self.name)
        else:
            self._find_device()
        self._consecutive_timeouts = 0
        self._failures = 0
        self._backoff = self.config.reconnect_initial_s
        self._next_attempt = 0.0
        self._last_number: int | None = None
        self._first_number: int | None = None
        self._timeline = Timeline(self.name, self._clock, self._sleep)
        self._clock_map = DeviceClock()
        self._start()

    def _close(self) -> None:
        self._stop()

    def _describe(self) -> dict[str, Any]:
        return {"serial": self.serial, "device": self.device_name, "playback": self.playback,
                "width": self.size[0], "height": self.size[1], "fps": self.fps, "has_depth": self._has_depth(),
                "depth_scale": self.depth_scale, "colour_format": self.colour_format,
                "depth_alignment": getattr(self, "_depth_mode", "none"),
                "intrinsics": self.intrinsics.to_json() if self.intrinsics else None, "imu": self.imu,
                "gyro": self.gyro, **(self._gravity.counters() if self._gravity is not None else {}),
                "infrared": self.infrared, "spectrum": self.spectrum,
                "infrared_intrinsics": self._infrared.intrinsics.to_json() if self._infrared else None,
                "realtime": self.config.realtime if self.playback else True}

    @property
    def infrared(self) -> str:
        """The infrared stream: ``in use`` (the last frame was its image) or ``standby`` while this start has a
        usable one; else ``off``, ``none`` (no infrared stream) or ``error: ...`` (why it is not used)."""
        if self._infrared is None:
            return self._infrared_unused
        return "in use" if self.spectrum == INFRARED else "standby"

    def _has_depth(self) -> bool:
        return self.depth_scale > 0.0

    # -- device and pipeline ------------------------------------------------------------------------------
    def _serials(self) -> list[str]:
        rs = self._rs
        out = []
        for dev in rs.context().query_devices():
            if dev.supports(rs.camera_info.serial_number):
                out.append(dev.get_info(rs.camera_info.serial_number))
        return out

    def _find_device(self) -> None:
        serials = self._serials()
        if not serials:
            raise SourceNotFound(
                "no RealSense camera found: plug one into a USB 3 port (check it with `rs-enumerate-devices`, "
                "or `lsusb` for vendor 8086), or use a v4l2: or file: source", self.name)
        if self.config.serial and self.config.serial not in serials:
            raise SourceNotFound(f"RealSense {self.config.serial} not found; connected: {', '.join(serials)}; set "
                                 "source.serial to one of them, or empty for the first camera", self.name)

    def _start(self) -> None:
        rs = self._rs
        c = self.config
        if self.playback is not None:
            # not rs.pipeline: it drops framesets when the reader is slow and may pair colour with the depth
            # of another frame (see hal.rs_playback)
            pipe = (self._pipeline_factory or PlaybackPipeline)(rs)  # a factory returns a PlaybackPipeline
            self._gravity = GravityEstimate() if c.imu else None
        else:
            pipe = (self._pipeline_factory or rs.pipeline)()  # a factory must return an rs.pipeline (subclass)
        self._infrared_asked = infrared = c.infrared != "off"
        try:
            if self.playback is None:
                profile = self._start_live(pipe)
            elif self._gravity is not None:
                profile = pipe.start(self.playback, c.depth, motion=sample_sink(rs, self._gravity), infrared=infrared)
            else:
                profile = pipe.start(self.playback, c.depth, infrared=infrared)
        except RuntimeError as exc:
            if self.playback is not None:
                raise SourceCorrupt(f"{self.playback}: librealsense cannot play this recording ({exc}); it may be "
                                    "truncated or corrupt — record it again (posed record -o NAME.db3)",
                                    self.name) from exc
            with_ir = " + infrared" if self._infrared_asked else ""
            ir_fix = (" (the infrared stream needs y8 at the colour's size and rate; source.infrared auto streams "
                      "without it when it cannot start)") if self._infrared_asked else ""
            raise SourceNotFound(
                f"RealSense {c.serial or '(first camera)'}: cannot start colour {c.width}x{c.height}@{c.fps:g}"
                f"{' + depth' if c.depth else ''}{with_ir} ({exc}); check the modes with `rs-enumerate-devices`"
                f"{ir_fix}, try 640x480@30, and that no other program holds the camera", self.name) from exc
        try:
            self._configure(pipe, profile)
        except Exception:
            _stop_quietly(pipe)
            raise
        self._pipe = pipe
        self.state = "streaming"

    def _live_config(self, infrared: bool) -> Any:
        rs = self._rs
        c = self.config
        cfg = rs.config()
        if c.serial:
            cfg.enable_device(c.serial)
        fps = int(round(c.fps))
        cfg.enable_stream(rs.stream.color, c.width, c.height, rs.format.bgr8, fps)
        if c.depth:
            cfg.enable_stream(rs.stream.depth, c.width, c.height, rs.format.z16, fps)
        if infrared:  # the left imager, at the colour's size: its image replaces colour's one for one
            cfg.enable_stream(rs.stream.infrared, INFRARED_INDEX, c.width, c.height, rs.format.y8, fps)
        return cfg

    def _start_live(self, pipe: Any) -> Any:
        """Start the camera (with the infrared stream unless ``off``); under ``auto`` a camera that cannot start
        with it starts without it and ``info["infrared"]`` says why (``_infrared_asked``: the last try's)."""
        self._infrared_error = ""
        try:
            return pipe.start(self._live_config(self._infrared_asked))
        except RuntimeError as exc:
            if not self._infrared_asked or self.config.infrared == "always":
                raise
            self._infrared_error = f"the camera cannot start with it ({exc}); streaming colour without it"
        self._infrared_asked = False
        return pipe.start(self._live_config(False))

    def _configure(self, pipe: Any, profile: Any) -> None:
        rs = self._rs
        dev = profile.get_device()
        streams = {s.stream_type(): s for s in profile.get_streams()}
        colour = streams.get(rs.stream.color)
        if colour is None:
            raise SourceUnsupported(f"{self.name}: no colour stream (streams: "
                                    f"{', '.join(str(s) for s in streams) or 'none'}); hal needs colour", self.name)
        vsp = colour.as_video_stream_profile()
        k = vsp.get_intrinsics()
        self.intrinsics = Intrinsics(float(k.fx), float(k.fy), float(k.ppx), float(k.ppy), int(k.width),
                                     int(k.height))
        self.size = (int(vsp.width()), int(vsp.height()))
        self.fps = float(vsp.fps())
        self.colour_format = str(colour.format()).split(".")[-1]
        if self.colour_format not in _CONVERSIONS:
            raise SourceUnsupported(f"{self.name}: colour format {self.colour_format} is not supported (use one of "
                                    f"{', '.join(_CONVERSIONS)})", self.name)
        self.depth_scale = 0.0
        self._depth_mode = "none"
        self._align = None
        depth = streams.get(rs.stream.depth)
        if self.config.depth and depth is not None:
            self.depth_scale = float(dev.first_depth_sensor().get_depth_scale())
            if _same_grid(depth, colour):
                self._depth_mode = "raw"  # recorded already aligned (posed record): keep it bit-exact
            else:
                self._depth_mode = "align"
                self._align = rs.align(rs.stream.color)
        self._configure_imu(dev, streams, colour)
        self._configure_infrared(profile, colour, depth if self._depth_mode != "none" else None)
        for key, attr in ((rs.camera_info.serial_number, "serial"), (rs.camera_info.name, "device_name")):
            if dev.supports(key):  # a software/played-back device may lack some infos
                setattr(self, attr, dev.get_info(key))

    def _configure_infrared(self, profile: Any, colour: Any, depth: Any) -> None:
        """The left infrared stream of this start, when it streams and is usable: the colour's size (its image
        replaces colour's pixel for pixel in the frame), its intrinsics, whether depth lies on its grid, and the
        rotation that turns gravity from the colour camera's axes into its own."""
        rs = self._rs
        self._infrared = None
        if self.config.infrared == "off":
            self._infrared_unused = "off"
            return
        ir = next((s for s in profile.get_streams() if s.stream_type() == rs.stream.infrared
                   and s.stream_index() == INFRARED_INDEX), None)
        if ir is None:
            self._infrared_unused = f"error: {self._infrared_error}" if self._infrared_error else "none"
            return
        k = ir.as_video_stream_profile().get_intrinsics()
        size, colour_size = (int(k.width), int(k.height)), self.size
        if size != colour_size:
            self._infrared_unused = (
                f"error: the infrared stream is {size[0]}x{size[1]}, the colour one {colour_size[0]}x{colour_size[1]}: "
                "an infrared image replaces a colour one only at the same size (record both streams at one size); "
                "colour only")
            return
        try:
            rotation = rotation_of(colour.get_extrinsics_to(ir))
        except RuntimeError:
            rotation = np.eye(3)  # not calibrated: the D400s' imagers agree within a degree
        self._infrared = _InfraredStream(
            intrinsics=Intrinsics(float(k.fx), float(k.fy), float(k.ppx), float(k.ppy), size[0], size[1]),
            depth_on_grid=depth is not None and _same_grid(depth, ir), rotation=rotation)

    def _configure_imu(self, dev: Any, streams: dict[Any, Any], colour: Any) -> None:
        """Gravity from the accelerometer: a recording's accel stream (already playing), or live the motion
        sensor opened and started here. Samples are in the depth sensor's axes (module doc of hal.imu)."""
        rs = self._rs
        if not self.config.imu:
            return
        rotation = np.eye(3)
        depth = streams.get(rs.stream.depth)
        if depth is not None:
            try:
                rotation = rotation_of(depth.get_extrinsics_to(colour))
            except RuntimeError:
                pass  # not calibrated: colour and depth axes agree within a degree on the D400s
        if self.playback is not None:
            has_accel = rs.stream.accel in streams
            self.imu = "streaming" if has_accel else "none"
            self.gyro = "streaming" if has_accel and rs.stream.gyro in streams else "none"
            if self._gravity is not None:
                self._gravity.rotation = rotation
            if not has_accel:
                self._gravity = None
            return
        found = find_accel(rs, dev)
        if found is None:
            self.imu, self.gyro, self._gravity = "none", "none", None
            return
        sensor, profile = found
        gyro = find_gyro(rs, sensor)   # on the accelerometer's motion sensor (D435i, D455), at its lowest rate
        self._gravity = GravityEstimate(rotation)
        try:
            sensor.open(profile if gyro is None else [profile, gyro])
            sensor.start(sample_sink(rs, self._gravity))
        except RuntimeError as exc:  # busy (another program streams it) or lost: colour and depth go on
            self.imu, self.gyro, self._gravity = f"error: {exc}", f"error: {exc}", None
            _stop_quietly(sensor, close=True)
            return
        self._imu_sensor = sensor
        self.imu = "streaming"
        self.gyro = "none" if gyro is None else "streaming"

    def _stop(self) -> None:
        sensor, self._imu_sensor = self._imu_sensor, None
        if sensor is not None:
            _stop_quietly(sensor, close=True)
        pipe, self._pipe = self._pipe, None
        if pipe is not None:
            _stop_quietly(pipe)

    def _hardware_reset(self) -> None:
        self.count("hardware_resets")
        if self.playback is not None:
            return  # nothing to reset; counted so the escalation is visible in info
        rs = self._rs
        try:
            for dev in rs.context().query_devices():
                ser = dev.get_info(rs.camera_info.serial_number) if dev.supports(rs.camera_info.serial_number) else ""
                if not self.config.serial or ser == self.config.serial:
                    dev.hardware_reset()
                    break
        except RuntimeError:
            pass
        self._next_attempt = max(self._next_attempt, self._clock() + RESET_SETTLE_S)

    def _device_present(self) -> bool:
        if self.playback is not None:
            return os.path.isfile(self.playback)
        try:
            serials = self._serials()
        except RuntimeError:
            return False
        return bool(serials) and (not self.config.serial or self.config.serial in serials)

    def _schedule_retry(self) -> None:
        self._next_attempt = max(self._next_attempt, self._clock() + self._backoff)
        self._backoff = min(self._backoff * 2.0, self.config.reconnect_max_s)

    def _reconnect(self, deadline: float) -> None:
        """Called while there is no pipeline: try to start one when the backoff allows, else wait and raise."""
        now = self._clock()
        if now < self._next_attempt:
            self._sleep(max(0.0, min(self._next_attempt, deadline) - now))
            if self._clock() < self._next_attempt:
                raise self._disconnected("waiting to reconnect")
        if not self._device_present():
            if self.state != "disconnected":
                self.count("disconnects")
            self.state = "disconnected"
            self._schedule_retry()
            raise self._disconnected("camera not found")
        try:
            self._start()
        except (SourceNotFound, SourceCorrupt, SourceUnsupported, RuntimeError) as exc:
            self.count("reopen_failures")
            self._failures += 1
            self.state = "reconnecting"
            if self._failures >= self.config.failures_before_reset:
                self._failures = 0
                self._hardware_reset()
            self._schedule_retry()
            raise self._disconnected(f"re-open failed: {exc}") from exc
        self.count("reopens")
        self._failures = 0
        self._backoff = self.config.reconnect_initial_s
        self._consecutive_timeouts = 0
        if self.playback is None:
            self._last_number = None  # a restarted camera may count its frames from 0 again
            self._first_number = None
            self._timeline.continue_seq()
            self._clock_map = DeviceClock()

    def _disconnected(self, why: str) -> SourceDisconnected:
        wait = max(0.0, self._next_attempt - self._clock())
        return SourceDisconnected(
            f"{self.name}: camera unavailable ({why}); retrying in {wait:.1f} s — check the USB cable and port; "
            "reading resumes by itself when it is back", self.name)

    def _lost(self, exc: Exception) -> SourceDisconnected:
        self._stop()
        self.count("disconnects")
        self.state = "disconnected"
        self._next_attempt = self._clock()
        return SourceDisconnected(f"{self.name}: the camera stopped ({exc}); reconnecting — check the USB cable",
                                  self.name)

    def _reopen_soon(self) -> None:
        """Too many timeouts in a row: stop the pipeline; the next read starts it again."""
        self._stop()
        self.state = "reconnecting"
        self._next_attempt = self._clock()

    # -- reading ------------------------------------------------------------------------------------------
    def _read(self, timeout_s: float) -> Frame:
        frame = self._timeline.read(timeout_s, lambda deadline: self._next_frame(deadline, timeout_s),
                                    realtime=self.playback is not None and self.config.realtime)
        self._consecutive_timeouts = 0
        return frame

    def _frame_period(self) -> float:
        """Seconds between two frames: the colour stream's rate, else ``source.fps``."""
        return 1.0 / (self.fps or self.config.fps)

    def _next_frame(self, deadline: float, timeout_s: float) -> Frame:
        if self._timeline.ended:
            raise EndOfStream(f"{self.name}: end of the recording (set source.loop=true to replay it again)",
                              self.name)
        while True:
            if self._pipe is None:
                self._reconnect(deadline)
            remaining = deadline - self._clock()
            if remaining <= 0:
                raise self._timed_out(timeout_s, self._reopen_soon)
            step = min(remaining, PLAYBACK_SLICE_S) if self.playback is not None else remaining
            try:
                ok, frames = self._pipe.try_wait_for_frames(max(1, int(step * 1000)))
            except RuntimeError as exc:
                raise self._lost(exc) from exc
            if not ok:
                if self.playback is not None and self._playback_finished():
                    self._end_of_file()
                continue
            arrival = self._clock()
            try:
                frame = self._to_frame(frames, arrival)
            except (RuntimeError, ValueError) as exc:
                # librealsense failed on this one frameset (its data, the alignment) or it held an image that is
                # not a frame: skip it, say so, and go on with the next (it escaped read() before: not a
                # SourceError, it ended the daemon's capture stage, which the supervisor restarted until it gave
                # up)
                self.count("corrupt")
                fix = "record the file again (posed record -o NAME.db3)" if self.playback else \
                    "check that the camera is on a USB 3 port and cable (rs-enumerate-devices shows the link)"
                raise SourceCorrupt(f"{self.name}: a frame could not be read ({type(exc).__name__}: "
                                    f"{str(exc).strip()[:200]}); skipping it — if this repeats, {fix}",
                                    self.name, fix=fix) from exc
            if frame is not None:
                return frame

    def _playback_finished(self) -> bool:
        return self._pipe.finished()

    def _end_of_file(self) -> None:
        looping = self._timeline.end_of_pass(self.config.loop, self._frame_period)
        self._stop()
        if not looping:
            self.state = "ended"
            raise EndOfStream(f"{self.name}: the recording ended after {self.counters['frames']} frames (set "
                              "source.loop=true or ?loop=true to replay it again)", self.name)
        self._last_number = None
        self.count("passes")
        self._start()

    def _to_frame(self, frames: Any, arrival: float) -> Frame | None:
        colour = frames.get_color_frame()
        if not colour:
            return None
        number = int(colour.get_frame_number())
        last = self._last_number
        if last is not None and (number <= last if self.playback is not None else number == last):
            self.count("duplicates")
            return None
        image = _CONVERSIONS[self.colour_format](np.asanyarray(colour.get_data()))
        ir = self._infrared_image(frames, image.shape[:2])
        spectrum = self._chooser.choose(image, ir is not None)
        intrinsics = self.intrinsics
        depth = None
        if spectrum == INFRARED:      # taken before any alignment: rs.align keeps colour and depth only
            image, intrinsics = _grey_to_bgr(ir), self._infrared.intrinsics
            d = frames.get_depth_frame() if self._infrared.depth_on_grid else None
            if d:
                depth = np.array(np.asanyarray(d.get_data()), dtype=np.uint16, copy=True)
        elif self._depth_mode != "none" and frames.get_depth_frame():
            if self._align is not None:
                frames = self._align.process(frames)
                colour = frames.get_color_frame()
            d = frames.get_depth_frame()
            if d:
                depth = np.array(np.asanyarray(d.get_data()), dtype=np.uint16, copy=True)
        if depth is not None and depth.shape != image.shape[:2]:
            depth = None  # never hand out depth that is not on the image's grid
        if self.playback is None and last is not None and number < last:
            self._timeline.continue_seq()  # the camera restarted its frame counter by itself
            self._first_number = number
        self._last_number = number
        if self._first_number is None:
            self._first_number = number
        t = self._timestamp(colour, arrival)
        seq = self._timeline.add_frame(number if self.playback is not None else number - self._first_number)
        if is_blank(image):       # a covered lens: nobody can be seen; said (hal.blank), its seq a gap
            self.count("blank")   # (a blank colour frame with an infrared image came as that image: hal.night)
            also = " (its infrared image too)" if spectrum == INFRARED else ""
            raise SourceCorrupt(f"{self.name}: {blank_message(image)}{also}; skipping it — {BLANK_FIX}", self.name,
                                fix=BLANK_FIX)
        # playback: the samples recorded up to this frame (the same gravity on every replay); live: every
        # sample so far (the motion sensor may stamp in another clock domain than colour)
        gravity = None if self._gravity is None else self._gravity.at(
            float(colour.get_timestamp()) / 1000.0 if self.playback is not None else math.inf)
        if spectrum == INFRARED:
            self.count("infrared_frames")
            if gravity is not None:   # the colour camera's axes -> the infrared imager's (the depth sensor's)
                g = self._infrared.rotation @ np.asarray(gravity)
                gravity = tuple(float(v) for v in g / np.linalg.norm(g))
        if spectrum != self.spectrum:
            self.count("spectrum_switches")
            self.spectrum = spectrum
        return Frame(image=image, depth=depth, depth_scale=self.depth_scale if depth is not None else 0.0, t=t,
                     seq=seq, intrinsics=intrinsics, gravity=gravity, spectrum=spectrum)

    def _infrared_image(self, frames: Any, size: tuple[int, int]) -> np.ndarray | None:
        """The frameset's left infrared image (uint8 H x W, the colour's size), or None."""
        if self._infrared is None:
            return None
        f = frames.get_infrared_frame(INFRARED_INDEX)
        if not f:
            return None
        ir = np.asanyarray(f.get_data())
        return ir if ir.shape == size else None

    def _timestamp(self, colour: Any, arrival: float) -> float:
        rs = self._rs
        ts_s = float(colour.get_timestamp()) / 1000.0
        if self.playback is not None:
            return self._timeline.time_at(self._timeline.since_first(ts_s), self._frame_period())
        domain = colour.get_frame_timestamp_domain()
        if domain in (rs.timestamp_domain.global_time, rs.timestamp_domain.system_time):
            return min(wall_to_monotonic(ts_s), arrival)
        return self._clock_map.map(ts_s, arrival)


@dataclass(frozen=True)
class _InfraredStream:
    """The usable left infrared stream of one start (``RealSenseSource._configure_infrared``)."""

    intrinsics: Intrinsics      # of its image (the colour's size)
    depth_on_grid: bool         # raw depth lies on its pixel grid: an infrared frame carries it
    rotation: np.ndarray        # 3 x 3: a vector in the colour camera's axes -> in the infrared imager's


def _same_grid(a: Any, b: Any) -> bool:
    """True when stream ``a``'s pixels are stream ``b``'s (same intrinsics, no distortion, identity pose): depth
    already on the colour grid (posed record), or raw depth on the left infrared imager's."""
    try:
        ka = a.as_video_stream_profile().get_intrinsics()
        kb = b.as_video_stream_profile().get_intrinsics()
        ext = a.get_extrinsics_to(b)
    except RuntimeError:
        return False
    same_k = (ka.width, ka.height) == (kb.width, kb.height) and all(
        abs(x - y) < 1e-3 for x, y in ((ka.fx, kb.fx), (ka.fy, kb.fy), (ka.ppx, kb.ppx), (ka.ppy, kb.ppy)))
    no_distortion = not any(ka.coeffs) and not any(kb.coeffs)
    identity = np.allclose(np.asarray(ext.rotation, float), np.eye(3).ravel(), atol=1e-6) and np.allclose(
        np.asarray(ext.translation, float), 0.0, atol=1e-6)
    return bool(same_k and no_distortion and identity)


def _stop_quietly(pipe: Any, close: bool = False) -> None:
    """Stop a pipeline or sensor (and close the sensor), ignoring librealsense's complaints."""
    for action in (pipe.stop, pipe.close) if close else (pipe.stop,):
        try:
            action()
        except RuntimeError:
            pass


def _grey_to_bgr(grey: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(np.ascontiguousarray(grey), cv2.COLOR_GRAY2BGR)


def _copy(image: np.ndarray) -> np.ndarray:
    return np.array(image, dtype=np.uint8, copy=True)


def _cvt(code_name: str) -> Callable[[np.ndarray], np.ndarray]:
    def convert(image: np.ndarray) -> np.ndarray:
        import cv2

        return cv2.cvtColor(image, getattr(cv2, code_name))
    return convert


_CONVERSIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "bgr8": _copy,
    "rgb8": _cvt("COLOR_RGB2BGR"),
    "bgra8": _cvt("COLOR_BGRA2BGR"),
    "rgba8": _cvt("COLOR_RGBA2BGR"),
    "yuyv": _cvt("COLOR_YUV2BGR_YUYV"),
}
