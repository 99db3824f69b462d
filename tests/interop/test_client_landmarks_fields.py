"""The client's landmarks carry the whole frame (docs/client.md, docs/formats.md ``posed.landmarks_frame``): real
frames with ``world`` and several ``people`` (the real ``posed landmarks`` on a real clip with two people),
made into the topic's message by the daemon's own payload function and published over a real Zenoh session
on 127.0.0.1 (multicast scouting off), reach ``PosedClient.on_landmarks("*", cb)`` with ``world``, ``people``
(track ids and their landmarks), ``gravity``, ``floor`` and ``raw`` equal to what was sent; a frame without
them gives None / empty, as before."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from posed.client import Landmarks, PersonLandmarks, PosedClient, contract
from posed.daemon import clock
from posed.daemon.bus import payloads
from posed.daemon.messages import FitMsg
from posed.daemon.stages.depth_floor import DepthFloor
from posed.falls.features import gravity_from_tilt
from posed.fitting import FitResult
from posed.landmarks import read_recording
from tests.daemon.depth_room import DEPTH_SCALE, Mount, render
from tests.daemon.zenoh_util import client as zenoh_client
from tests.daemon.zenoh_util import free_port, router
from tests.interop.daemons import ROOT, URFD

ROBOT = "lmf1"
CLIP = "reference/multi_person/bend_hand.mp4"     # a man bends over a planter, a woman stands watching
MOUNT = Mount(1.25, 28.0, -2.5)


@pytest.fixture(scope="module")
def two_people(tmp_path_factory, shared_data):
    """(header, frames) of the real ``posed landmarks`` run on the real two-person clip."""
    out = tmp_path_factory.mktemp("lmf") / "bend_hand.landmarks.jsonl"
    run = subprocess.run([sys.executable, "-m", "posed.cli", "landmarks", str(shared_data / CLIP), "-o", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    header, frames, problems = read_recording(out)
    assert problems == [] and frames
    return header, frames


def _message(frame, image_size, seq: int) -> dict:
    """The landmarks topic's object for ``frame`` as the daemon makes it (daemon.bus.payloads), as JSON."""
    msg = FitMsg(result=FitResult(seq, frame.t, ok=False, reason="not fitted here"), landmarks=replace(frame, seq=seq),
                 t_capture=clock.now(), image_size=tuple(image_size))
    obj = json.loads(payloads.dumps(payloads.landmarks_message(msg, ROBOT)))
    assert contract.errors(obj) == [], contract.errors(obj)
    return obj


def _rows(rows) -> np.ndarray:
    return np.array([[np.nan] * 5 if r is None else r for r in rows], dtype=float)


def _floor_field() -> dict:
    """The ``floor`` field the daemon's landmark stage computes (daemon.stages.depth_floor) on a rendered room's
    depth image with the accelerometer's gravity as prior."""
    cam = MOUNT.camera(640, 480)
    depth, _ = render(cam)
    floor = DepthFloor()
    assert floor.offer(depth, DEPTH_SCALE, cam.intrinsics, gravity_from_tilt(MOUNT.tilt_deg, MOUNT.roll_deg), 0.0)
    field = floor.field(0.2)
    assert field is not None and "height_m" in field and field["prior"] == "imu"
    return field


def _publish_until_received(rep: str, messages: dict[int, dict], timeout: float = 30.0) -> dict[int, Landmarks]:
    """Put each message on posed/ROBOT/landmarks (again, until the route exists) from a real Zenoh session and
    return what ``on_landmarks("*", cb)`` got, by seq."""
    got: dict[int, tuple[str, Landmarks]] = {}
    errors: list = []
    lock = threading.Lock()

    def on_landmarks(robot: str, lm: Landmarks) -> None:
        with lock:
            got.setdefault(lm.seq, (robot, lm))

    pub = zenoh_client(rep)
    try:
        with PosedClient.connect(rep, wait_s=30) as c:
            c.on_landmarks("*", on_landmarks, on_error=lambda k, e: errors.append((k, e)))
            deadline = time.monotonic() + timeout
            while True:
                with lock:
                    missing = [s for s in messages if s not in got]
                if not missing:
                    break
                assert time.monotonic() < deadline, f"never received seq {missing}"
                for s in missing:
                    pub.put(f"posed/{ROBOT}/landmarks", json.dumps(messages[s]), encoding=payloads.JSON_ENCODING)
                time.sleep(0.2)
            assert errors == [] and c.decode_errors == 0, errors
    finally:
        pub.close()
    assert all(robot == ROBOT for robot, _ in got.values())
    return {s: lm for s, (_, lm) in got.items()}


@pytest.fixture
def zenoh_router():
    """A router on 127.0.0.1 (the stand-in for zenohd, multicast scouting off) for the publisher and the client."""
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    try:
        yield rep
    finally:
        r.close()


def test_world_people_gravity_and_floor_reach_the_client(two_people, shared_data, zenoh_router):
    header, frames = two_people
    many = next(f for f in frames if f.people is not None and len(f.people) >= 2 and f.world is not None)
    assert all(p.world is not None for p in many.people)
    gravity = tuple(float(v) for v in gravity_from_tilt(MOUNT.tilt_deg, MOUNT.roll_deg))
    with_imu = replace(many, gravity=gravity, extra={**many.extra, "floor": _floor_field()})
    _, urfd = read_recording(shared_data / URFD / "urfd_00_fall.landmarks.jsonl")[:2]
    one = next(f for f in urfd if f.landmarks is not None)
    nobody = next(f for f in urfd if f.landmarks is None)
    sent = {1: _message(many, header.image_size, 1), 2: _message(with_imu, header.image_size, 2),
            3: _message(one, (640, 480), 3), 4: _message(nobody, (640, 480), 4)}
    assert len(sent[1]["people"]) >= 2 and "world" in sent[1] and "gravity" not in sent[1]
    assert sent[2]["gravity"] == list(gravity) and sent[2]["floor"]["height_m"] > 0
    assert not {"world", "people", "gravity", "floor", "depth_m"} & set(sent[3])

    got = _publish_until_received(zenoh_router, sent)

    # several people, with the world landmarks: the values sent, and the whole message in raw
    lm = got[1]
    assert lm.robot == ROBOT and lm.raw == sent[1] and lm.image_size == tuple(header.image_size)
    np.testing.assert_array_equal(lm.points, _rows(sent[1]["landmarks"]))
    np.testing.assert_array_equal(lm.points, many.landmarks)
    assert lm.world.shape == (33, 5) and lm.world.dtype == np.float64
    np.testing.assert_array_equal(lm.world, _rows(sent[1]["world"]))
    np.testing.assert_array_equal(lm.world, many.world)
    assert [p.id for p in lm.people] == [p["id"] for p in sent[1]["people"]] == [p.id for p in many.people]
    assert all(isinstance(p, PersonLandmarks) for p in lm.people)
    for mine, wire, truth in zip(lm.people, sent[1]["people"], many.people, strict=True):
        np.testing.assert_array_equal(mine.landmarks, _rows(wire["landmarks"]))
        np.testing.assert_array_equal(mine.landmarks, truth.landmarks)
        np.testing.assert_array_equal(mine.world, truth.world)
        assert mine.depth_m is None
        assert mine == PersonLandmarks.from_json(wire)
    assert lm.people[0] != lm.people[1]
    # the frame's own landmarks are one of the people's (the one followed longest)
    assert any(np.array_equal(p.landmarks, lm.points, equal_nan=True) for p in lm.people)
    assert lm.gravity is None and lm.floor is None and lm.depth_m is None
    with pytest.raises(AttributeError):
        lm.world = None                                    # frozen

    # gravity and the depth floor as the daemon's landmark stage puts them on a frame
    lm = got[2]
    assert lm.gravity == gravity and lm.floor == sent[2]["floor"] and lm.raw == sent[2]
    assert lm.floor["height_m"] == pytest.approx(MOUNT.height_m, abs=0.05)
    assert [p.id for p in lm.people] == [p.id for p in many.people]

    # one person without world landmarks (another extractor): None / empty, the rest as before
    lm = got[3]
    assert lm.world is None and lm.people == () and lm.gravity is None and lm.floor is None and lm.depth_m is None
    np.testing.assert_array_equal(lm.points, one.landmarks)
    assert lm.raw == sent[3] and lm.image_size == (640, 480) and lm.time_unix == sent[3]["time_unix"]
    # nobody in view
    lm = got[4]
    assert lm.points is None and lm.world is None and lm.people == () and lm.raw == sent[4]


def test_a_bad_person_is_a_decode_error_naming_it():
    base = {"seq": 1, "t": 0.0, "landmarks": None, "image_size": [640, 480]}
    row = [1.0, 2.0, 0.0, 0.9, 0.9]
    with pytest.raises(ValueError, match=r"people\[0\]\.id must be a non-negative integer"):
        Landmarks.from_json({**base, "people": [{"id": -1, "landmarks": [row] * 33}]})
    with pytest.raises(ValueError, match=r"people\[1\]: landmarks must be a list of 33 entries or null, got 3"):
        Landmarks.from_json({**base, "people": [{"id": 1, "landmarks": [row] * 33}, {"id": 2, "landmarks": [row] * 3}]})
    with pytest.raises(ValueError, match="world must be a list of 33 entries or null, got 2"):
        Landmarks.from_json({**base, "world": [row, row]})
    # a malformed gravity is kept in raw and never used, as the daemon's reader does (docs/formats.md)
    lm = Landmarks.from_json({**base, "gravity": [0.0, "down", 1.0], "floor": "?", "future_field": {"a": 1}})
    assert lm.gravity is None and lm.floor is None and lm.raw["gravity"] == [0.0, "down", 1.0]
    assert lm.raw["future_field"] == {"a": 1}
