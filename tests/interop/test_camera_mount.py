"""The one input the robot's own software puts: where the camera is (``posed/ROBOT/camera/mount``,
``posed.camera_mount``, docs/formats.md). Its schema on valid and invalid shapes; the client's
``set_camera_mount`` on a real Zenoh session on 127.0.0.1 (the bytes a subscriber gets are the documented
message) and on bad arguments (a ValueError naming the argument and the choices, nothing put); and the geometry
helpers of ``client.mount`` against rotations worked out by hand, and against the fall detector's own tilt and
roll convention (``falls.features.gravity_from_tilt``)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

from posed.client import PosedClient, contract, mount_from_rotation, quaternion_matrix
from posed.client.mount import camera_mount_message
from posed.falls.features import gravity_from_tilt
from tests.daemon.zenoh_util import config, free_port

BASE = {"format": "posed.camera_mount", "version": 1}

VALID = [
    {**BASE, "down": [0.0, 1.0, 0.0]},
    {**BASE, "down": [0.02, 9.6, 2.1]},                      # any length: an accelerometer's m/s^2
    {**BASE, "down": [0, 0, -1]},                            # integers are numbers
    {**BASE, "tilt_deg": 12.5, "roll_deg": -3.0, "height_m": 1.1},
    {**BASE, "tilt_deg": -90, "roll_deg": 90, "height_m": 0.05, "valid_s": 3600},
    {**BASE, "down": [0.1, 0.9, 0.3], "height_m": 5, "valid_s": 0.05, "time_unix": 1.8e9, "source": "tf2 head"},
    {"down": [0.0, 1.0, 0.0]},                               # format and version are optional
    {"tilt_deg": 0, "roll_deg": 0},
    {**BASE, "down": [0.0, 1.0, 0.0], "robot": "kitchen", "seq": 7},    # unknown fields are ignored
]

INVALID = {
    "nothing": {**BASE},
    "down all zero": {**BASE, "down": [0, 0.0, -0.0]},
    "down of two": {**BASE, "down": [0.0, 1.0]},
    "down of four": {**BASE, "down": [0.0, 1.0, 0.0, 0.0]},
    "down as text": {**BASE, "down": [0.0, "1", 0.0]},
    "down a boolean": {**BASE, "down": [True, 1.0, 0.0]},
    "down not a list": {**BASE, "down": {"x": 0, "y": 1, "z": 0}},
    "tilt without roll": {**BASE, "tilt_deg": 10.0},
    "roll without tilt": {**BASE, "roll_deg": 10.0},
    "down and tilt and roll": {**BASE, "down": [0, 1, 0], "tilt_deg": 10.0, "roll_deg": 0.0},
    "down and tilt": {**BASE, "down": [0, 1, 0], "tilt_deg": 10.0},
    "down and roll": {**BASE, "down": [0, 1, 0], "roll_deg": 0.0},
    "tilt over 90": {**BASE, "tilt_deg": 90.5, "roll_deg": 0.0},
    "roll under -90": {**BASE, "tilt_deg": 0.0, "roll_deg": -91},
    "height too low": {**BASE, "down": [0, 1, 0], "height_m": 0.04},
    "height too high": {**BASE, "down": [0, 1, 0], "height_m": 5.01},
    "height as text": {**BASE, "down": [0, 1, 0], "height_m": "1.2"},
    "valid_s 0": {**BASE, "down": [0, 1, 0], "valid_s": 0},
    "valid_s over an hour": {**BASE, "down": [0, 1, 0], "valid_s": 3601},
    "time_unix 0": {**BASE, "down": [0, 1, 0], "time_unix": 0},
    "time_unix as text": {**BASE, "down": [0, 1, 0], "time_unix": "now"},
    "source a number": {**BASE, "down": [0, 1, 0], "source": 3},
    "source too long": {**BASE, "down": [0, 1, 0], "source": "x" * 129},
    "another format": {"format": "posed.ack", "version": 1, "down": [0, 1, 0]},
    "version 2": {**BASE, "version": 2, "down": [0, 1, 0]},
    "not an object": [0, 1, 0],
}


@pytest.mark.parametrize("msg", VALID, ids=range(len(VALID)))
def test_valid_messages_pass(msg):
    assert contract.errors(msg, "camera_mount") == []
    contract.validate({**BASE, **msg})


@pytest.mark.parametrize("name", INVALID)
def test_each_invalid_shape_fails(name):
    assert contract.errors(INVALID[name], "camera_mount"), name


def test_the_message_builder_sends_what_it_was_given():
    assert camera_mount_message(down=(0, 2, 0)) == {**BASE, "down": [0.0, 2.0, 0.0], "valid_s": 1.0}
    msg = camera_mount_message(tilt_deg=np.float32(20.0), roll_deg=-5, height_m=1.25, valid_s=0.3,
                               time_unix=1_800_000_000.5, source="head")
    assert msg == {**BASE, "tilt_deg": 20.0, "roll_deg": -5.0, "height_m": 1.25, "valid_s": 0.3,
                   "time_unix": 1_800_000_000.5, "source": "head"}
    assert all(type(v) is float for k, v in msg.items() if k not in ("format", "version", "source"))
    assert contract.errors(msg) == []


BAD_ARGS = [
    (dict(), "down=.*or tilt_deg and roll_deg"),
    (dict(down=[0, 1, 0], tilt_deg=5.0, roll_deg=0.0), "not both"),
    (dict(down=[0, 1, 0], roll_deg=0.0), "not both"),
    (dict(tilt_deg=5.0), "tilt_deg without roll_deg: give both"),
    (dict(roll_deg=5.0), "roll_deg without tilt_deg: give both"),
    (dict(down=[0, 0, 0]), "all 0"),
    (dict(down=[0, 1]), "has 2 values"),
    (dict(down=5.0), "down=5.0: give"),
    (dict(down=[0, float("nan"), 1]), r"down\[1\]=nan is not finite: give three finite numbers"),
    (dict(down=[0, float("inf"), 1]), r"down\[1\]=inf"),
    (dict(down=["0", 1, 0]), r"down\[0\]='0'"),
    (dict(tilt_deg=95.0, roll_deg=0.0), "tilt_deg=95.0 is outside -90..90"),
    (dict(tilt_deg=0.0, roll_deg=-120), "roll_deg=-120 is outside -90..90"),
    (dict(down=[0, 1, 0], height_m=0.0), "height_m=0.0 is outside 0.05..5: give metres"),
    (dict(down=[0, 1, 0], height_m=True), "height_m=True"),
    (dict(down=[0, 1, 0], valid_s=0.0), "valid_s=0.0 is outside 0.05..3600"),
    (dict(down=[0, 1, 0], valid_s=None), "valid_s=None"),
    (dict(down=[0, 1, 0], time_unix=-1.0), "time_unix=-1.0: give unix seconds"),
    (dict(down=[0, 1, 0], time_unix=float("nan")), "time_unix=nan"),
    (dict(down=[0, 1, 0], source=42), "source=42: give free text"),
    (dict(down=[0, 1, 0], source="x" * 129), "at most 128 printable"),
    (dict(down=[0, 1, 0], source="head\ncamera"), "at most 128 printable"),
    (dict(down=[1e-10, 0, 0]), "all 0"),
]


@pytest.mark.parametrize(("kwargs", "says"), BAD_ARGS, ids=[s for _, s in BAD_ARGS])
def test_a_bad_argument_is_named_with_its_choices(kwargs, says):
    with pytest.raises(ValueError, match=says):
        camera_mount_message(**kwargs)


# ------------------------------------------------------------------ on a real Zenoh session
@pytest.fixture
def bus():
    """A peer listening on 127.0.0.1 (as the daemon does), a PosedClient connected to it, the endpoint."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(config("peer", listen=[ep])) as listener:
        with PosedClient.connect(ep, wait_s=10) as posed:
            yield listener, posed, ep


def _collect(session, key: str) -> tuple[list, threading.Event]:
    got: list = []
    arrived = threading.Event()

    def on_sample(s) -> None:
        got.append((str(s.key_expr), str(s.encoding), s.payload.to_bytes()))
        arrived.set()

    session.declare_subscriber(key, on_sample)
    return got, arrived


def _put_until_heard(put, arrived: threading.Event, timeout: float = 10.0):
    """Put until the subscriber heard one (a put before the route exists may be lost), return what was put."""
    deadline = time.monotonic() + timeout
    while True:
        sent = put()
        if arrived.wait(0.2):
            return sent
        assert time.monotonic() < deadline, "nothing arrived"


def test_set_camera_mount_puts_the_documented_message(bus):
    listener, posed, _ = bus
    got, arrived = _collect(listener, "posed/**")
    sent = _put_until_heard(lambda: posed.set_camera_mount(
        "kitchen", down=[0.05, 0.96, 0.27], height_m=1.12, valid_s=0.25, time_unix=1_800_000_000.25,
        source="tf2 base_link->camera_color_optical_frame"), arrived)
    time.sleep(0.3)
    key, encoding, payload = got[-1]
    assert key == "posed/kitchen/camera/mount"
    assert encoding == "application/json"
    msg = json.loads(payload.decode("utf-8"))
    assert msg == sent == {"format": "posed.camera_mount", "version": 1, "down": [0.05, 0.96, 0.27],
                           "height_m": 1.12, "valid_s": 0.25, "time_unix": 1_800_000_000.25,
                           "source": "tf2 base_link->camera_color_optical_frame"}
    assert contract.errors(msg) == []
    assert {k for k, _, _ in got} == {"posed/kitchen/camera/mount"}

    # tilt and roll, time left to the daemon (when received), default valid_s
    got.clear()
    arrived.clear()
    _put_until_heard(lambda: posed.set_camera_mount("kitchen", tilt_deg=14.0, roll_deg=-2.5), arrived)
    assert json.loads(got[-1][2]) == {"format": "posed.camera_mount", "version": 1, "tilt_deg": 14.0,
                                      "roll_deg": -2.5, "valid_s": 1.0}


@pytest.mark.parametrize(("robot", "kwargs", "says"), [
    ("*", dict(down=[0, 1, 0]), "give one robot id"),
    ("kit*", dict(down=[0, 1, 0]), "give one robot id"),
    ("a/b", dict(down=[0, 1, 0]), "give one robot id"),
    ("", dict(down=[0, 1, 0]), "give one robot id"),
    (" kitchen", dict(down=[0, 1, 0]), "give one robot id"),
    ("kitchen", dict(down=[0, 0, 0]), "all 0"),
    ("kitchen", dict(down=[0, 1, 0], tilt_deg=3.0, roll_deg=0.0), "not both"),
    ("kitchen", dict(tilt_deg=3.0), "give both"),
    ("kitchen", dict(down=[0, 1, 0], height_m=9.0), "height_m=9.0 is outside 0.05..5"),
])
def test_a_bad_call_raises_and_puts_nothing(bus, robot, kwargs, says):
    listener, posed, _ = bus
    got, arrived = _collect(listener, "posed/**")
    _put_until_heard(lambda: posed.set_camera_mount("probe", down=[0, 1, 0]), arrived)   # the route is there
    time.sleep(0.3)
    got.clear()
    with pytest.raises(ValueError, match=says):
        posed.set_camera_mount(robot, **kwargs)
    posed.set_camera_mount("probe", down=[0, 1, 0], source="after")        # a later good put still arrives
    deadline = time.monotonic() + 5
    while not any(b"after" in p for _, _, p in got) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert {k for k, _, _ in got} == {"posed/probe/camera/mount"}, got


# ------------------------------------------------------------------ the geometry (docs/ros2.md)
def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pitched_down(a: float) -> np.ndarray:
    """World-from-camera of an optical frame looking along world +x, pitched down by ``a`` (by hand: its
    columns are the camera's x (image right), y (image down) and z (forward) axes in the world, z up)."""
    x_c = [0.0, -1.0, 0.0]
    y_c = [-math.sin(a), 0.0, -math.cos(a)]
    z_c = [math.cos(a), 0.0, -math.sin(a)]
    return np.array([x_c, y_c, z_c]).T


def test_mount_from_rotation_by_hand():
    # level, looking ahead: down is image-down (+y)
    m = mount_from_rotation(_pitched_down(0.0).T, 1.30)
    assert m.down == pytest.approx((0.0, 1.0, 0.0), abs=1e-12) and m.height_m == pytest.approx(1.30)
    # pitched down 30 degrees: down is (0, cos 30, sin 30) = (0, 0.866, 0.5) in the camera's axes
    m = mount_from_rotation(_pitched_down(math.radians(30)).T, 1.30, floor_z_m=0.10)
    assert m.down == pytest.approx((0.0, math.sqrt(3) / 2, 0.5), abs=1e-12)
    assert m.height_m == pytest.approx(1.20)
    # looking straight down (a ceiling camera): down is forward (+z)
    assert mount_from_rotation(_pitched_down(math.pi / 2).T).down == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    # rolled 90 degrees clockwise (seen from behind): the image's right (+x) points down
    rolled = _pitched_down(0.0) @ _rz(math.pi / 2)
    assert mount_from_rotation(rolled.T).down == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)
    assert mount_from_rotation(np.eye(3), None).height_m is None


@pytest.mark.parametrize(("yaw", "tilt", "roll"), [(0, 0, 0), (37, 12, 0), (-120, 25, -8), (200, -15, 30),
                                                    (90, 60, 45)])
def test_mount_from_rotation_follows_the_detectors_tilt_and_roll(yaw, tilt, roll):
    """The robot's heading does not matter; pitch down and clockwise roll are falls.camera_tilt_deg's and
    camera_roll_deg's (the detector's own conversion, gravity_from_tilt)."""
    world_from_camera = _rz(math.radians(yaw)) @ _pitched_down(math.radians(tilt)) @ _rz(math.radians(roll))
    m = mount_from_rotation(world_from_camera.T, 0.9)
    assert m.down == pytest.approx(tuple(gravity_from_tilt(tilt, roll)), abs=1e-12)
    assert math.hypot(*m.down) == pytest.approx(1.0)


def test_quaternion_matrix_by_hand():
    assert quaternion_matrix(0, 0, 0, 1) == pytest.approx(np.eye(3))
    assert quaternion_matrix(0, 0, 0, -2) == pytest.approx(np.eye(3))                      # normalised
    s = math.sqrt(0.5)
    assert quaternion_matrix(0, 0, s, s) == pytest.approx(np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]]))  # 90° z
    assert quaternion_matrix(1, 0, 0, 0) == pytest.approx(np.diag([1.0, -1.0, -1.0]))                     # 180° x
    # a level optical frame on a base (x ahead, z up): the usual base->optical quaternion of ROS drivers
    assert quaternion_matrix(-0.5, 0.5, -0.5, 0.5) == pytest.approx(_pitched_down(0.0))
    with pytest.raises(ValueError, match="not all 0"):
        quaternion_matrix(0, 0, 0, 0)


def test_a_matrix_that_is_not_a_rotation_is_refused():
    with pytest.raises(ValueError, match="3x3"):
        mount_from_rotation(np.eye(4))
    with pytest.raises(ValueError, match="not a rotation"):
        mount_from_rotation(np.diag([1.0, 1.0, -1.0]))          # a mirror
    with pytest.raises(ValueError, match="not a rotation"):
        mount_from_rotation(2 * np.eye(3))


# ------------------------------------------------------------------ docs/ros2.md's node, with stand-ins for ROS
FAKE_ROS = {
    "rclpy/__init__.py": '''
import time as _clock                # not `time`: rclpy.time, the submodule, takes that name
def init():
    pass
def spin(node):                      # a few timer ticks, then back (rclpy.spin would run until shut down)
    for _ in range(40):
        for cb in node._timers:
            cb()
        _clock.sleep(0.05)
''',
    "rclpy/node.py": '''
class _Log:
    def warn(self, text):
        print("WARN", text)
class Node:
    def __init__(self, name):
        self.name, self._timers = name, []
    def create_timer(self, period, cb):
        assert period == 0.1
        self._timers.append(cb)
    def get_logger(self):
        return _Log()
''',
    "rclpy/time.py": '''
class Time:
    def __init__(self, seconds=0, nanoseconds=0):
        assert (seconds, nanoseconds) == (0, 0)     # Time(): the latest transform
''',
    "tf2_ros.py": '''
import json, os
from types import SimpleNamespace as NS
class TransformException(Exception):
    pass
class TransformListener:
    def __init__(self, buffer, node):
        pass
class Buffer:
    calls = 0
    def lookup_transform(self, target, source, when):
        Buffer.calls += 1
        if Buffer.calls == 1:
            raise TransformException("frame does not exist yet")
        t = json.loads(os.environ["FAKE_TF"])
        assert (target, source) == (t["target"], t["source"])
        return NS(header=NS(stamp=NS(sec=t["sec"], nanosec=t["nanosec"])),
                  transform=NS(translation=NS(**t["p"]), rotation=NS(**t["q"])))
''',
}


def _qmul(a, b):
    """Hamilton product of quaternions (x, y, z, w): the rotation of a, then b in a's frame."""
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)


def test_the_ros2_example_puts_what_tf2_says(bus, tmp_path):
    """docs/ros2.md's node as written, with rclpy and tf2_ros replaced by stand-ins (no ROS 2 here) whose tf2
    says: the optical frame 1.20 m above base_footprint, pitched down 30 degrees and rolled 10 degrees
    clockwise. What reaches a subscriber is the mount falls' own convention gives for that tilt and roll."""
    listener, _, ep = bus
    doc = (Path(__file__).resolve().parents[2] / "docs" / "ros2.md").read_text()
    [code] = [b for b in re.findall(r"```python\n(.*?)```", doc, re.S) if "set_camera_mount" in b]
    for rel, text in FAKE_ROS.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    a, b = math.radians(30), math.radians(10)
    level = (-0.5, 0.5, -0.5, 0.5)                      # a level optical frame on the base
    q = _qmul(_qmul(level, (-math.sin(a / 2), 0, 0, math.cos(a / 2))), (0, 0, math.sin(b / 2), math.cos(b / 2)))
    assert quaternion_matrix(*q) == pytest.approx(_pitched_down(a) @ _rz(b))     # the stand-in's pose, by hand
    tf = {"target": "base_footprint", "source": "camera_color_optical_frame", "sec": 1_800_000_000,
          "nanosec": 250_000_000, "p": {"x": 0.1, "y": 0.0, "z": 1.2}, "q": dict(zip("xyzw", q, strict=True))}
    got, arrived = _collect(listener, "posed/**")
    out = subprocess.run([sys.executable, "-c", code.replace("tcp/127.0.0.1:7447", ep)],
                         capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONPATH": str(tmp_path), "FAKE_TF": json.dumps(tf)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert "WARN no base_footprint -> camera_color_optical_frame" in out.stdout
    assert arrived.wait(5), "the node put nothing"
    for key, _, payload in got:
        msg = json.loads(payload)
        assert key == "posed/kitchen/camera/mount" and contract.errors(msg) == []
        assert msg["down"] == pytest.approx(list(gravity_from_tilt(30, 10)), abs=1e-9)
        assert msg["height_m"] == pytest.approx(1.2) and msg["valid_s"] == 0.3
        assert msg["time_unix"] == 1_800_000_000.25
        assert msg["source"] == "tf2 base_footprint->camera_color_optical_frame"


def test_the_client_md_example_puts_its_mount(bus):
    """docs/client.md's set_camera_mount lines, as written, against the listener."""
    listener, _, ep = bus
    doc = (Path(__file__).resolve().parents[2] / "docs" / "client.md").read_text()
    [code] = [b for b in re.findall(r"```python\n(.*?)```", doc, re.S) if "set_camera_mount" in b]
    got, arrived = _collect(listener, "posed/**")
    deadline = time.monotonic() + 30
    while not arrived.is_set():               # a put made before the route exists may be lost: run it again
        out = subprocess.run([sys.executable, "-c", code.replace("tcp/127.0.0.1:7447", ep)], capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 0, out.stderr[-2000:]
        assert arrived.wait(1.0) or time.monotonic() < deadline, "the example put nothing"
    key, _, payload = got[0]
    assert key == "posed/kitchen/camera/mount"
    assert json.loads(payload) == {"format": "posed.camera_mount", "version": 1, "tilt_deg": 18.0,
                                   "roll_deg": 0.0, "height_m": 1.05, "valid_s": 0.5, "source": "head"}
