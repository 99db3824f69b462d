"""The V4L2 source when the camera misbehaves, at the hardware edge (a scripted capture object in place of
OpenCV's): frames in a pixel format the driver did not convert, empty and garbage buffers, a driver that
raises, blank (black) frames, a frozen stream, a kernel timestamp that steps back. Each must give a clear
error naming what the camera sent and what to do, and the source must go on (or reconnect) by itself."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest

from posed.hal import v4l2 as v4l2_mod
from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceDisconnected, SourceTimeout
from posed.hal.v4l2 import V4L2Source


@pytest.fixture(scope="module")
def image(squat_frames):
    return cv2.resize(squat_frames[0], (640, 480))


def noisy(image, n):
    """A real camera's frame: the scene plus sensor noise (two real frames are never byte-identical)."""
    rng = np.random.default_rng(n)
    return np.clip(image.astype(np.int16) + rng.integers(-3, 4, image.shape), 0, 255).astype(np.uint8)


class Camera:
    """A capture factory: each opened capture plays ``per_open[k]`` (a list of frames, or of exceptions to
    raise), then good noisy frames forever; ``ms`` (optional) gives CAP_PROP_POS_MSEC per frame."""

    def __init__(self, image, per_open, fps=100.0, ms=None):
        self.image = image
        self.per_open = list(per_open)
        self.fps = fps
        self.ms = ms
        self.opens = 0
        self.sent = 0
        self.lock = threading.Lock()

    def factory(self, device, api):
        with self.lock:
            script = self.per_open[self.opens] if self.opens < len(self.per_open) else []
            self.opens += 1
        return Capture(self, list(script))


class Capture:
    def __init__(self, cam, script):
        self.cam = cam
        self.script = script
        self.pos_ms = 0.0

    def isOpened(self):
        return True

    def set(self, prop, value):
        return True

    def get(self, prop):
        return {cv2.CAP_PROP_FRAME_WIDTH: 640.0, cv2.CAP_PROP_FRAME_HEIGHT: 480.0, cv2.CAP_PROP_FPS: 30.0,
                cv2.CAP_PROP_POS_MSEC: self.pos_ms}.get(prop, 0.0)

    def read(self):
        time.sleep(1.0 / self.cam.fps)
        with self.cam.lock:
            n = self.cam.sent
            self.cam.sent += 1
        if self.cam.ms is not None:
            self.pos_ms = self.cam.ms(n)
        if self.script:
            item = self.script.pop(0)
            if isinstance(item, Exception):
                raise item
            return True, item
        return True, noisy(self.cam.image, n)

    def release(self):
        pass


def source(cam, **cfg):
    base = dict(type="v4l2", device="/dev/video0", width=640, height=480, fps=30.0, read_timeout_s=0.5,
                reconnect_initial_s=0.02, reconnect_max_s=0.1)
    base.update(cfg)
    return V4L2Source(SourceConfig(**base), capture_factory=cam.factory)


def read_until_frame(src, seconds=5.0):
    """Read until a frame comes; the errors met on the way."""
    errors = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            return src.read(0.5), errors
        except (SourceCorrupt, SourceDisconnected, SourceTimeout) as exc:
            errors.append(exc)
    raise AssertionError(f"no frame within {seconds} s; errors: {[str(e) for e in errors]}")


def test_packed_yuyv_frames_are_converted_not_a_crash(image):
    # a driver handing over YUYV unconverted (2 channels) made Frame() raise ValueError out of read(): the
    # daemon's capture stage died on every frame and the supervisor escalated (exit 70)
    yuyv = cv2.cvtColor(image, cv2.COLOR_BGR2YUV_YUYV) if hasattr(cv2, "COLOR_BGR2YUV_YUYV") else None
    if yuyv is None:
        yuv = cv2.cvtColor(image, cv2.COLOR_BGR2YUV)
        yuyv = np.empty((480, 640, 2), np.uint8)
        yuyv[:, :, 0] = yuv[:, :, 0]
        yuyv[:, 0::2, 1] = yuv[:, 0::2, 1]
        yuyv[:, 1::2, 1] = yuv[:, 0::2, 2]
    # as two channels, and as the raw buffer (one row of width x height x 2 bytes) OpenCV gives unconverted
    cam = Camera(image, [[yuyv, yuyv.reshape(1, -1)]], fps=5.0)     # slow: every frame is read
    with source(cam) as src:
        frames = []
        for _ in range(2):
            frame, errors = read_until_frame(src)
            assert errors == []
            frames.append(frame)
    for frame in frames:
        assert frame.image.shape == (480, 640, 3) and frame.image.dtype == np.uint8
        assert np.abs(frame.image.astype(int) - image.astype(int)).mean() < 12   # the same picture, in colour


def test_raw_mjpeg_is_decoded_and_garbage_or_empty_frames_are_corrupt(image):
    ok, jpeg = cv2.imencode(".jpg", image)
    assert ok
    garbage = np.arange(5000, dtype=np.uint8)[None, :]                    # a raw buffer, not an image
    cut = jpeg[: jpeg.size // 3].reshape(-1)                              # an MJPEG frame cut short
    cam = Camera(image, [[jpeg.reshape(-1), garbage, np.zeros((0, 0, 3), np.uint8), cut]], fps=10.0)
    with source(cam) as src:
        first = src.read(1.0)
        assert first.image.shape == (480, 640, 3)                         # decoded, not a 1 x N "image"
        problems = []
        while len(problems) < 3:
            try:
                src.read(1.0)
                break
            except SourceCorrupt as exc:
                problems.append(exc)
        frame, _ = read_until_frame(src)                                  # then good frames again
        info = src.info
    text = [str(p) for p in problems]
    assert any("raw buffer of 5000 values, not an image" in t for t in text), text
    assert any("empty frame" in t for t in text), text
    assert all("v4l2:/dev/video0" in t and "USB cable" in t for t in text), text
    assert all(p.fix for p in problems)
    assert frame.image.shape == (480, 640, 3)
    assert info["corrupt"] >= 2


def test_a_driver_that_raises_is_reconnected_not_silent_forever(image):
    # an exception from cap.read() (cv2.error from the V4L2 backend) ended the reader thread: every read then
    # timed out, "re-opening the camera" reopened nothing, and the daemon stayed blind until restarted
    cam = Camera(image, [[cv2.error("VIDIOC_DQBUF: No such device")]])
    with source(cam) as src:
        frame, errors = read_until_frame(src)
        info = src.info
    assert frame.image.shape == (480, 640, 3)
    assert any(isinstance(e, SourceDisconnected) and "VIDIOC_DQBUF: No such device" in str(e) for e in errors), \
        [str(e) for e in errors]
    assert cam.opens >= 2 and info["disconnects"] == 1


def test_blank_frames_are_not_handed_out_and_say_why(image, monkeypatch):
    # a covered lens: every frame black (and so all alike). Said as blank frames, each skipped, never taken for
    # a frozen stream (a reopen does not uncover a lens)
    monkeypatch.setattr(v4l2_mod, "FROZEN_AFTER_S", 0.2)
    black = np.zeros((480, 640, 3), np.uint8)
    cam = Camera(image, [[black.copy() for _ in range(60)]])
    with source(cam) as src:
        frame, errors = read_until_frame(src)
        info = src.info
    assert cam.opens == 1 and info["frozen"] == 0
    assert errors and all(isinstance(e, SourceCorrupt) for e in errors)
    text = str(errors[0])
    assert "blank frames" in text and "black" in text and "covered lens" in text, text
    assert "uncover the camera's lens" in errors[0].fix
    assert info["blank"] >= 1
    assert frame.image.max() > 0                                          # the scene, once uncovered


def test_the_uniform_green_of_a_stream_of_zeros_is_blank(image):
    # a YUYV buffer of zeros (a UVC stream that lost its data) converts to one flat green: blank too, whatever
    # its colour (it was taken for a scene: its channels differ, 0 and 135)
    cam = Camera(image, [[np.zeros((480, 640, 2), np.uint8)]], fps=10.0)
    with source(cam) as src:
        frame, errors = read_until_frame(src)
        info = src.info
    assert len(errors) == 1 and isinstance(errors[0], SourceCorrupt) and "blank frames" in str(errors[0])
    assert "black" not in str(errors[0])
    assert info["blank"] == 1


def test_a_dark_but_real_frame_is_handed_out(image):
    dark = noisy((image // 20).astype(np.uint8), 1)                       # a dim room: dark, but a scene
    cam = Camera(image, [[dark]])
    with source(cam) as src:
        frame = src.read(1.0)
    assert np.array_equal(frame.image, dark)


def test_a_frozen_stream_is_reopened(image, monkeypatch):
    monkeypatch.setattr(v4l2_mod, "FROZEN_AFTER_S", 0.3)
    stuck = noisy(image, 99)
    cam = Camera(image, [[stuck] * 200], fps=100.0)                       # 2 s of the very same bytes
    with source(cam) as src:
        errors = []
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and cam.opens < 2:
            try:
                src.read(0.5)
            except (SourceCorrupt, SourceDisconnected, SourceTimeout) as exc:
                errors.append(exc)
        frame, more = read_until_frame(src)
        info = src.info
    errors += more
    assert cam.opens >= 2, "a frozen camera was never reopened"
    assert info["frozen"] == 1
    assert any(isinstance(e, SourceDisconnected) and "same image over and over" in str(e) for e in errors), \
        [str(e) for e in errors]
    assert not np.array_equal(frame.image, stuck)


def test_timestamps_never_go_back(image):
    # kernel buffer times, except one frame whose stamp is implausible (arrival time used), after which the
    # next kernel stamp lies before that arrival: t stepped back
    def ms(n):
        now = time.monotonic()
        return (now - 5.0) * 1000.0 if n == 3 else (now - 0.2) * 1000.0

    cam = Camera(image, [], ms=ms)
    with source(cam) as src:
        ts = [src.read(1.0).t for _ in range(8)]
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False)), ts
