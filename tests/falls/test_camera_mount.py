"""The camera's pose from the robot in the fall detector (``FallDetector.set_camera_mount``, source ``robot``):
it comes first for the gravity (ahead of the IMU, the depth floor, what was learned and the config) and its
height first for the floor; nothing is learned from people while it holds, the kept geometry is what was
learned before it, and None goes back to the other sources as they were."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.falls.camera_geometry import CameraGeometry
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from tests.falls.scene_runs import judge_scene

EVIDENCE = {"age_s": 0.05, "source": "tf:base_link->camera_color_optical_frame", "samples": 12}


def _sources(geo: CameraGeometry) -> tuple[str, str, str]:
    s = geo.summary()
    return s["tilt_from"], s["roll_from"], s["height_from"]


def test_the_robot_comes_first_then_imu_depth_learned_config():
    """Each source added in turn from the bottom; then taken away from the top: each one in its place."""
    cfg = FallsConfig(camera_tilt_deg=5.0, camera_roll_deg=0.0, camera_height_m=0.9, camera_roll_auto=True)
    geo = CameraGeometry(cfg)
    assert _sources(geo) == ("config", "config", "config")
    up = -gravity_from_tilt(5.0, 3.0)                     # people standing rolled 3 deg: the roll is learned
    for _ in range(80):
        geo.learn(up, np.cross(up, [0.0, 0.0, 1.0]), 0.1)
    learned = geo.summary()
    assert learned["roll_from"] == "learned"
    geo.set_depth_floor(gravity_from_tilt(20.0, 1.0), 1.4)
    assert _sources(geo) == ("depth", "depth", "depth")
    geo.set_imu(gravity_from_tilt(22.0, -1.0) * 9.81)
    assert _sources(geo) == ("imu", "imu", "depth")
    assert geo.set_robot(gravity_from_tilt(30.0, 2.0) * 3.0, 1.25, EVIDENCE)
    assert _sources(geo) == ("robot", "robot", "robot")
    s = geo.summary()
    assert s["tilt_deg"] == pytest.approx(30.0) and s["roll_deg"] == pytest.approx(2.0)
    assert s["floor_below_camera_m"] == pytest.approx(1.25) and geo.metric_floor() == pytest.approx(1.25)
    assert s["robot_mount"] == {"height_m": 1.25, **EVIDENCE}
    assert geo.used() == {"gravity": "robot", "floor": "robot", "config": "measured",
                          "depth_floor": geo.used()["depth_floor"], "robot_mount": {"height_m": 1.25, **EVIDENCE}}
    # an IMU that starts, a new IMU reading or depth floor while the robot holds change nothing
    late = CameraGeometry(cfg)
    late.set_robot(gravity_from_tilt(30.0, 2.0), None)
    assert not late.set_imu(gravity_from_tilt(5.0, 0.0)) and late.summary()["tilt_deg"] == pytest.approx(30.0)
    assert not late.set_depth_floor(gravity_from_tilt(12.0, 0.0), 1.0) and late.summary()["tilt_from"] == "robot"
    assert not geo.set_imu(gravity_from_tilt(10.0, 0.0))
    assert not geo.set_depth_floor(gravity_from_tilt(12.0, 0.0), 1.0)
    assert geo.summary()["tilt_deg"] == pytest.approx(30.0) and geo.floor_below_camera == pytest.approx(1.25)
    # taken away from the top
    assert geo.set_robot(None, None)
    assert _sources(geo) == ("imu", "imu", "depth")
    assert geo.summary()["tilt_deg"] == pytest.approx(10.0)
    geo.set_imu(None)
    assert _sources(geo) == ("depth", "depth", "depth")
    geo.set_depth_floor(None)
    assert geo.summary()["roll_from"] == "learned" and geo.summary()["tilt_from"] == "config"
    assert geo.summary()["roll_deg"] == pytest.approx(learned["roll_deg"], abs=1.0)   # the learner, not the robot


def test_robot_gravity_without_height_leaves_the_floor_to_the_other_sources():
    geo = CameraGeometry(FallsConfig(camera_height_m=1.1))
    geo.set_depth_floor(gravity_from_tilt(20.0), 1.4)
    geo.set_robot(gravity_from_tilt(20.5), None, EVIDENCE)
    assert _sources(geo) == ("robot", "robot", "depth")
    assert geo.floor_below_camera == pytest.approx(1.4 / math.cos(math.radians(0.5)), abs=1e-6)
    assert "height_m" not in geo.used()["robot_mount"]
    geo.set_depth_floor(None)
    assert _sources(geo) == ("robot", "robot", "config") and geo.floor_below_camera == pytest.approx(1.1)


def test_from_one_robot_pose_to_the_next_nothing_is_forgotten():
    """The robot tilting its head: each pose is used as it comes, the motion kept (as for the IMU)."""
    det = FallDetector(FallsConfig(), "r1", fit_frame="camera")
    assert det.set_camera_mount(gravity_from_tilt(10.0), 1.2, EVIDENCE)       # from the config: a new source
    assert not det.set_camera_mount(gravity_from_tilt(25.0), 1.3, EVIDENCE)   # the head moved
    assert det.geometry["tilt_deg"] == pytest.approx(25.0) and det.floor_below_camera == pytest.approx(1.3)
    assert det.set_camera_mount(None, None)                                   # forgotten: the config again
    assert det.geometry["tilt_from"] == det.geometry["height_from"] == "config"
    assert det.geometry["tilt_deg"] == pytest.approx(0.0) and det.floor_below_camera == pytest.approx(1.0)
    assert "robot_mount" not in det.geometry
    assert not det.set_camera_mount(None, None)                               # nothing to forget twice


@pytest.mark.parametrize("down,height", [((0.0, 0.0, 0.0), 1.0), ((np.nan, 1.0, 0.0), 1.0), ((0.0, 1.0), 1.0),
                                         ((0.0, 1.0, 0.0), 0.0), ((0.0, 1.0, 0.0), math.inf),
                                         ((0.0, 1.0, 0.0), -1.0)])
def test_a_broken_pose_is_refused_and_changes_nothing(down, height):
    det = FallDetector(FallsConfig(), "r1")
    det.set_camera_mount(gravity_from_tilt(20.0), 1.1)
    with pytest.raises(ValueError, match="down|height"):
        det.set_camera_mount(np.array(down), height)
    assert det.geometry["tilt_deg"] == pytest.approx(20.0) and det.floor_below_camera == pytest.approx(1.1)


def test_learning_pauses_while_the_robot_gives_the_pose_and_the_kept_geometry_is_the_learned_one():
    cfg = FallsConfig(camera_tilt_auto=True, camera_roll_auto=True)
    geo = CameraGeometry(cfg)
    up = -gravity_from_tilt(0.0, 4.0)
    for _ in range(60):                                       # 6 s of a standing person: the roll is learned
        geo.learn(up, np.cross(up, [0.0, 0.0, 1.0]), 0.1)
        geo.observe_body_axis(up, 0.1)
    for _ in range(6):
        geo.observe_floor(1.05)
    before = geo.state()
    assert geo.summary()["roll_from"] == "learned" and geo.floor_below_camera == pytest.approx(1.05)
    seen = {k: geo.summary()[k] for k in ("standing_s", "body_s")}
    geo.set_robot(gravity_from_tilt(35.0, -2.0), 2.0, EVIDENCE)
    robot_up = -gravity_from_tilt(35.0, -2.0)
    for _ in range(100):                                      # people seen along the robot's pose: not learned
        assert not geo.learn(robot_up, np.cross(robot_up, [0.0, 0.0, 1.0]), 0.1)
        assert not geo.observe_body_axis(robot_up, 0.1)
        assert not geo.observe_seated_trunk(robot_up, 0.1)
        geo.observe_floor(1.9)
    assert {k: geo.summary()[k] for k in seen} == seen        # the learners paused
    assert geo.state() == before                              # the file keeps what was learned from people
    assert geo.set_robot(None, None)                          # back: as it was, floor and all
    after = geo.state()
    assert {**after, "gravity": None} == {**before, "gravity": None}
    # the gravity in use is the learner's estimate afresh (before, it lagged it by less than a 1 deg step)
    assert float(np.dot(after["gravity"], before["gravity"])) > math.cos(math.radians(1.0))
    s = geo.summary()
    assert s["roll_from"] == "learned" and s["height_from"] == "learned"
    assert geo.floor_below_camera == pytest.approx(1.05)
    assert "robot_mount" not in s and "robot_mount" not in geo.used()


def test_the_robot_is_not_kept_across_restarts():
    geo = CameraGeometry(FallsConfig())
    geo.set_robot(gravity_from_tilt(30.0), 1.5, EVIDENCE)
    again = CameraGeometry(FallsConfig())
    assert again.restore(geo.state()) is None
    assert _sources(again) == ("config", "config", "config")


WALL = {sc.name: sc for sc in catalogue("tune", "wall")}


def _run(sc, robot: bool):
    def mount(det, cam):
        det.set_camera_mount(gravity_from_tilt(cam.tilt, cam.roll), cam.z, EVIDENCE)

    return judge_scene(sc, mount if robot else None)


def test_a_person_found_lying_on_a_wall_camera_is_found_with_the_robots_pose():
    """Nobody stood in view: the default guess (level, 1 m) misses a person lying on the floor of a camera 2 m up
    and 35 deg down; with the robot's pose they are found, and the event says which geometry it used."""
    sc = WALL["wall/tune/fall/standing-sideways/fast-v30"]
    lying = [fr for fr in frames(sc) if fr.t >= sc.truth.t_impact + 0.5]

    def judge(robot: bool):
        det = FallDetector(FallsConfig(), "r1", fit_frame="camera")
        cam = sc.camera
        out = []
        for fr in lying:
            if robot:
                det.set_camera_mount(gravity_from_tilt(cam.tilt, cam.roll), cam.z, EVIDENCE)
            out += det.update(truth_result(fr, cam), fr.landmarks, (cam.width, cam.height), cam.intrinsics)
        return out

    assert [e for e in judge(False) if e.state in ("falling", "on_floor")] == []
    found = [e for e in judge(True) if e.state == "on_floor"]
    assert found
    geometry = found[0].extra["geometry"]
    assert (geometry["gravity"], geometry["floor"]) == ("robot", "robot")
    assert geometry["robot_mount"] == {"height_m": sc.camera.z, **EVIDENCE}


def test_a_wall_camera_fall_is_judged_with_the_robots_pose():
    sc = WALL["wall/tune/fall/standing-backward/fast-v100"]
    det, events = _run(sc, robot=True)
    first = next(e for e in events if e.state in ("falling", "on_floor"))
    assert 0.0 <= first.t_detect - sc.truth.t_impact <= 1.5
    assert first.extra["geometry"]["gravity"] == "robot"
    assert det.geometry["tilt_deg"] == pytest.approx(sc.camera.tilt, abs=1e-6)
