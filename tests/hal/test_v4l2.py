"""The V4L2 source with a scripted capture object at the hardware edge (frames, stalls, an unplug) and the
real OpenCV V4L2 backend for a device that does not exist."""

from __future__ import annotations

import threading
import time
from collections import deque

import cv2
import numpy as np
import pytest

from posed import hal
from posed.camera_model import Intrinsics
from posed.hal.config import SourceConfig
from posed.hal.v4l2 import V4L2Source

PROPS = {cv2.CAP_PROP_FOURCC: "FOURCC", cv2.CAP_PROP_FRAME_WIDTH: "WIDTH", cv2.CAP_PROP_FRAME_HEIGHT: "HEIGHT",
         cv2.CAP_PROP_FPS: "FPS", cv2.CAP_PROP_BUFFERSIZE: "BUFFERSIZE"}


class ScriptedCamera:
    """A UVC camera as the driver shows it: 640x480 only, ``fps`` frames/s, kernel timestamps, and a script of
    ("frames", n) / ("stall", seconds) / ("unplug", seconds) steps; afterwards it streams forever."""

    def __init__(self, images, script, fps=50.0):
        self.images = images
        self.script = deque(script)
        self.fps = fps
        self.absent_until = 0.0
        self.opens: list[float] = []
        self.settings: list[tuple[str, float]] = []
        self.sent = 0
        self.lock = threading.Lock()

    def factory(self, device, api):
        assert api == cv2.CAP_V4L2
        self.opens.append(time.monotonic())
        return FakeCapture(self, present=time.monotonic() >= self.absent_until)

    def next_step(self):
        with self.lock:
            if not self.script:
                return ("frames", 1)
            kind, value = self.script[0]
            if kind == "frames":
                if value <= 1:
                    self.script.popleft()
                else:
                    self.script[0] = ("frames", value - 1)
                return ("frames", 1)
            self.script.popleft()
            return (kind, value)


class FakeCapture:
    def __init__(self, cam: ScriptedCamera, present: bool):
        self.cam = cam
        self.open = present
        self.props = {cv2.CAP_PROP_FRAME_WIDTH: 640.0, cv2.CAP_PROP_FRAME_HEIGHT: 480.0, cv2.CAP_PROP_FPS: 30.0,
                      cv2.CAP_PROP_FOURCC: float(cv2.VideoWriter_fourcc(*"YUYV")), cv2.CAP_PROP_BUFFERSIZE: 4.0,
                      cv2.CAP_PROP_POS_MSEC: 0.0}

    def isOpened(self):
        return self.open

    def set(self, prop, value):
        self.cam.settings.append((PROPS.get(prop, str(prop)), value))
        if prop in (cv2.CAP_PROP_FOURCC, cv2.CAP_PROP_BUFFERSIZE, cv2.CAP_PROP_FPS):
            self.props[prop] = float(value)
        return True  # width/height: this camera only does 640x480

    def get(self, prop):
        return self.props.get(prop, 0.0)

    def read(self):
        if not self.open:
            return False, None
        kind, value = self.cam.next_step()
        if kind == "stall":
            time.sleep(value)
        elif kind == "unplug":
            self.cam.absent_until = time.monotonic() + value
            self.open = False
            return False, None
        time.sleep(1.0 / self.cam.fps)
        image = self.cam.images[self.cam.sent % len(self.cam.images)]
        self.cam.sent += 1
        self.props[cv2.CAP_PROP_POS_MSEC] = (time.monotonic() - 0.004) * 1000.0  # kernel buffer time
        return True, image.copy()

    def release(self):
        self.open = False


@pytest.fixture(scope="module")
def images(squat_frames):
    return [cv2.resize(f, (640, 480)) for f in squat_frames[:8]]


def make(images, script, **cfg):
    cam = ScriptedCamera(images, script)
    base = dict(type="v4l2", device="/dev/video0", width=1280, height=720, fps=30.0, read_timeout_s=0.5,
                reconnect_initial_s=0.02, reconnect_max_s=0.16)
    base.update(cfg)
    return cam, V4L2Source(SourceConfig(**base), capture_factory=cam.factory)


def test_settings_frames_intrinsics_and_kernel_timestamps(images):
    cam, src = make(images, [], fx=600.0)
    opened = time.monotonic()
    with src:
        frames = [src.read(1.0) for _ in range(3)]
        info = src.info
    closed = time.monotonic()
    assert [name for name, _ in cam.settings] == ["FOURCC", "WIDTH", "HEIGHT", "FPS", "BUFFERSIZE"]
    assert dict(cam.settings)["BUFFERSIZE"] == 1
    assert (info["width"], info["height"], info["fourcc"], info["buffer_size"]) == (640, 480, "MJPG", 1)
    assert info["timestamps"] == "kernel"
    assert all(any(np.array_equal(f.image, im) for im in images) for f in frames)
    assert [f.seq for f in frames] == sorted({f.seq for f in frames})
    assert frames[0].intrinsics == Intrinsics(600.0, 600.0, 319.5, 239.5, 640, 480)
    # the kernel's buffer time: the camera stamps each frame 4 ms before read() returns it, on the monotonic
    # clock, between opening and closing the source
    assert all(opened - 0.004 <= f.t <= closed for f in frames)


def test_newest_frame_wins_when_the_reader_is_slow(images):
    cam, src = make(images, [])
    with src:
        first = src.read(1.0)
        sent = cam.sent  # first.seq < sent: frames are counted from 0 and first was among them
        deadline = time.monotonic() + 10  # 10 frames at 50 fps take 0.2 s: 9.8 s of scheduling slack
        while cam.sent < sent + 10 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert cam.sent >= sent + 10, "the scripted camera stopped sending"
        second = src.read(1.0)
        dropped = src.info["dropped"]
    # 10 more frames came from the driver; all but possibly the last were published (it may still be on its
    # way from read() to the reader's buffer), so the newest is at least seq sent + 8 >= first.seq + 9, and
    # each frame between the two reads was replaced before anyone read it
    assert second.seq - first.seq >= 9 and dropped >= second.seq - first.seq - 1


def test_stall_bounded_reads_then_reopen_after_n_timeouts(images):
    # The driver stalls for 4 s. A read that waited on the stalled driver would return only when it ends, so
    # each 0.1 s read must come back within its timeout plus 1 s of scheduling slack, far below the stall
    # (and the three of them, <= 3.3 s, end before the stall does).
    stall = 4.0
    cam, src = make(images, [("frames", 3), ("stall", stall)], read_timeout_s=0.1, timeouts_before_reopen=3)
    with src:
        for _ in range(3):
            src.read(1.0)
        errors = []
        for _ in range(3):
            t0 = time.monotonic()
            with pytest.raises(hal.SourceTimeout) as exc:
                src.read(0.1)
            errors.append(str(exc.value))
            assert time.monotonic() - t0 < 0.1 + 1.0  # never hangs on the stalled driver
        assert "3 times in a row; re-opening" in errors[-1]
        frame = src.read(stall + 2.0)  # the stalled grab returns, the camera is re-opened and streams again
        info = src.info
    assert len(cam.opens) == 2 and info["reopens"] == 1 and info["timeouts"] == 3
    assert frame.seq >= 3


def test_unplug_reconnects_with_exponential_backoff(images):
    # Backoff 0.125 s doubling to 0.5 s while the camera is gone for 3 s: attempts 0.25, 0.5, 0.5, ... s apart
    # (never closer: the next attempt is scheduled after the failed one). A gap can be longer than its backoff
    # by scheduling delay, allowed 1 s; the failures the bounds separate are further apart: no doubling
    # (gaps of 0.125 s, below the lower bound) and no cap (0.25, 0.5, 1, then 2 s > 0.5 + 1 s, still unplugged).
    initial, cap, unplugged = 0.125, 0.5, 3.0
    cam, src = make(images, [("frames", 2), ("unplug", unplugged)], read_timeout_s=0.1,
                    reconnect_initial_s=initial, reconnect_max_s=cap)
    with src:
        src.read(1.0), src.read(1.0)
        t0 = time.monotonic()
        with pytest.raises(hal.SourceDisconnected, match="unplugged or stopped sending.*check the USB cable"):
            src.read(10.0)
        # at once: a read that missed the unplug would wait its whole 10 s timeout before raising
        assert time.monotonic() - t0 < 10.0 / 2
        assert src.info["state"] == "disconnected"
        kinds = []
        while True:
            try:
                frame = src.read(0.1)
                break
            except hal.SourceDisconnected:
                kinds.append("disconnected")
            assert time.monotonic() - t0 < unplugged + cap + 5.0, "never reconnected"
        info = src.info
    assert kinds and frame.seq >= 2 and info["disconnects"] == 1 and info["state"] == "streaming"
    gaps = np.diff(cam.opens[1:])  # attempts while the device was gone, then the successful one
    assert len(gaps) >= 4  # 4 failed attempts are due by 1.375 s of the 3 s
    expected = [min(initial * 2 ** (i + 1), cap) for i in range(len(gaps))]
    for gap, want in zip(gaps, expected, strict=True):
        assert want * 0.9 <= gap <= want + 1.0, (gaps, expected)
    # came back only once the device was there again, and not before
    assert all(t < cam.absent_until for t in cam.opens[1:-1]) and cam.opens[-1] >= cam.absent_until


def test_missing_device_messages(images):
    cam, src = make(images, [], device="/dev/video-missing")
    cam.absent_until = time.monotonic() + 60
    with pytest.raises(hal.SourceNotFound, match="/dev/video-missing: no such video device.*v4l2-ctl"):
        src.open()
    cam, src = make(images, [], device="0")
    cam.absent_until = time.monotonic() + 60
    with pytest.raises(hal.SourceNotFound, match="cannot be opened.*group 'video'"):
        src.open()


def test_real_opencv_v4l2_without_a_device():
    src = hal.open_source("v4l2:/dev/video97?read_timeout_s=10")
    assert isinstance(src, V4L2Source)
    t0 = time.monotonic()
    with pytest.raises(hal.SourceNotFound, match="/dev/video97: no such video device"):
        src.open()
    # reported by the first open: no retry, no wait for a frame. The shortest wait the source could have
    # made is one read timeout (source.read_timeout_s, 10 s here); half of it is the bound.
    assert time.monotonic() - t0 < src.config.read_timeout_s / 2


def test_close_is_prompt_and_idempotent(images):
    # close() joins the reader thread for at most read_timeout_s + 1 s (then leaves it, a daemon thread).
    # With a 5 s read timeout a reader that did not see the stop would hold close() for 6 s; a prompt one
    # returns at its next frame (20 ms), leaving 3 s of scheduling slack below half of that; its thread is gone.
    cam, src = make(images, [], read_timeout_s=5.0)
    before = set(threading.enumerate())
    src.open()
    src.read(1.0)
    t0 = time.monotonic()
    src.close()
    src.close()
    assert time.monotonic() - t0 < (5.0 + 1.0) / 2 and src.info["state"] == "closed"
    assert not [t for t in set(threading.enumerate()) - before if t.name.startswith("hal-v4l2")]
    with pytest.raises(hal.SourceError, match="not open"):
        src.read(0.1)
