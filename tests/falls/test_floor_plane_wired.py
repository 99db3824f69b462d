"""The floor measured in the depth image as a source of the fall detector's camera geometry (issue 33 item 1a;
falls.camera_geometry.CameraGeometry.set_depth_floor): a measured floor beats a guessed, configured or learned
one; an IMU still gives the gravity, the depth floor then the height; each event says which it used."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.falls.camera_geometry import CameraGeometry
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from posed.falls.geometry import tilt_roll_deg
from tests.falls.scene_runs import judge_scene

EVIDENCE = {"inliers": 2400, "fraction": 0.61, "rms_m": 0.007, "age_s": 0.4}


def test_a_measured_floor_beats_the_guess_the_config_and_the_feet():
    geo = CameraGeometry(FallsConfig())                       # the default guess: level, 1 m
    assert geo.used()["gravity"] == "config" and geo.floor_below_camera == 1.0
    assert geo.set_depth_floor(gravity_from_tilt(25.0, -3.0) * 2.0, 1.3, EVIDENCE)    # gravity changed
    s = geo.summary()
    assert (s["tilt_from"], s["roll_from"], s["height_from"]) == ("depth", "depth", "depth")
    assert s["tilt_deg"] == pytest.approx(25.0) and s["roll_deg"] == pytest.approx(-3.0)
    assert s["floor_below_camera_m"] == pytest.approx(1.3)
    assert s["depth_floor"] == {"height_m": 1.3, **EVIDENCE}
    assert geo.used() == {"gravity": "depth", "floor": "depth", "config": "guess",
                          "depth_floor": {"height_m": 1.3, **EVIDENCE}}
    # a floor learned from standing feet, a measured configured mount: the depth floor still wins
    for _ in range(10):
        geo.observe_floor(1.1)
    assert geo.floor_below_camera == pytest.approx(1.3) and geo.used()["floor"] == "depth"
    measured = CameraGeometry(FallsConfig(camera_tilt_deg=10.0, camera_height_m=0.9))
    assert measured.measured
    measured.set_depth_floor(gravity_from_tilt(12.0, 0.5), 0.95)
    assert measured.summary()["tilt_deg"] == pytest.approx(12.0) and measured.floor_below_camera == pytest.approx(0.95)


def test_a_refreshed_floor_within_a_degree_keeps_the_gravity_and_the_motion():
    geo = CameraGeometry(FallsConfig())
    assert geo.set_depth_floor(gravity_from_tilt(25.0, 0.0), 1.3)
    assert not geo.set_depth_floor(gravity_from_tilt(25.4, 0.3), 1.31)   # noise of the fit: nothing to forget
    assert geo.floor_below_camera == pytest.approx(1.31, abs=1e-3)


def test_with_an_imu_the_gravity_is_the_imus_and_the_height_the_depth_floors():
    geo = CameraGeometry(FallsConfig())
    geo.set_imu(gravity_from_tilt(20.0, 1.0) * 9.81)
    n = gravity_from_tilt(21.5, 0.0)                          # the plane's normal, 1-2 deg from the IMU's
    assert not geo.set_depth_floor(n, 1.2, EVIDENCE)          # the IMU's gravity stays
    s = geo.summary()
    assert (s["tilt_from"], s["height_from"]) == ("imu", "depth")
    assert s["tilt_deg"] == pytest.approx(20.0) and s["roll_deg"] == pytest.approx(1.0)
    # the floor's distance along the IMU's gravity: h / cos(angle between them)
    assert geo.floor_below_camera == pytest.approx(1.2 / float(n @ geo.gravity))
    assert geo.used()["gravity"] == "imu" and geo.used()["floor"] == "depth"
    geo.set_imu(None)                                         # the IMU gone: the depth floor's gravity
    assert geo.summary()["tilt_from"] == "depth" and geo.summary()["tilt_deg"] == pytest.approx(21.5)


def test_forgetting_the_depth_floor_returns_to_the_other_sources():
    geo = CameraGeometry(FallsConfig(camera_tilt_deg=5.0, camera_height_m=0.8))
    geo.set_depth_floor(gravity_from_tilt(30.0), 1.5)
    assert geo.set_depth_floor(None)                          # gravity back to the configured one
    s = geo.summary()
    assert (s["tilt_from"], s["height_from"], s["floor_below_camera_m"]) == ("config", "config", 0.8)
    assert "depth_floor" not in s and "depth_floor" not in geo.used()
    assert not geo.set_depth_floor(None)                      # nothing to forget


@pytest.mark.parametrize("down,height", [((0.0, 0.0, 0.0), 1.0), ((np.nan, 1.0, 0.0), 1.0), ((0.0, 1.0), 1.0),
                                         ((0.0, 1.0, 0.0), 0.0), ((0.0, 1.0, 0.0), math.inf),
                                         ((0.0, 1.0, 0.0), -1.0)])
def test_a_broken_plane_is_refused_and_changes_nothing(down, height):
    geo = CameraGeometry(FallsConfig())
    geo.set_depth_floor(gravity_from_tilt(20.0), 1.1)
    with pytest.raises(ValueError, match="floor|height"):
        geo.set_depth_floor(down, height)
    assert geo.floor_below_camera == pytest.approx(1.1) and tilt_roll_deg(geo.gravity)[0] == pytest.approx(20.0)


def test_the_depth_floor_is_live_not_kept_across_restarts():
    geo = CameraGeometry(FallsConfig())
    geo.set_depth_floor(gravity_from_tilt(30.0), 1.5)
    again = CameraGeometry(FallsConfig())
    assert again.restore(geo.state()) is None
    assert again.summary()["height_from"] == "config" and "depth_floor" not in again.summary()


WALL = {sc.name: sc for sc in catalogue("tune", "wall")}


def _run(sc, depth_floor: bool):
    def plane(det, cam):      # the landmark stage's plane, refreshed every frame (0.5 mm, 0.1 deg of noise)
        det.set_floor_plane(gravity_from_tilt(cam.tilt + 0.1, cam.roll - 0.1), cam.z + 0.0005, EVIDENCE)

    return judge_scene(sc, plane if depth_floor else None)


@pytest.mark.parametrize("name", ["wall/tune/fall/standing-sideways/fast-v30",
                                  "wall/tune/fall/standing-backward/fast-v100"])
def test_a_wall_camera_fall_is_judged_with_the_depth_floor_and_says_so(name):
    """A camera 2 m up, 35 deg down, the config told nothing: with the depth floor the fall is caught on the
    measured geometry from the first frame, and the event says so (not the standing body's guess)."""
    sc = WALL[name]
    det, events = _run(sc, depth_floor=True)
    first = next(e for e in events if e.state in ("falling", "on_floor"))
    assert 0.0 <= first.t_detect - sc.truth.t_impact <= 1.5
    geometry = first.extra["geometry"]
    assert (geometry["gravity"], geometry["floor"]) == ("depth", "depth")
    assert geometry["depth_floor"]["inliers"] == EVIDENCE["inliers"]
    assert det.geometry["tilt_deg"] == pytest.approx(sc.camera.tilt, abs=0.2)
    assert det.geometry["floor_below_camera_m"] == pytest.approx(sc.camera.z, abs=0.01)


def test_wall_camera_daily_activities_raise_nothing_with_the_depth_floor():
    for name in ("wall/tune/adl/sit-down-chair/normal-v30", "wall/tune/adl/lie-on-bed-side/normal-v30",
                 "wall/tune/adl/squat/quick-v100", "wall/tune/adl/bend-pick-up/normal-v30"):
        _, events = _run(WALL[name], depth_floor=True)
        assert events == [], name


def test_a_person_found_lying_before_anyone_stood_is_judged_with_the_depth_floor():
    """Nothing to learn the geometry from (nobody stood in view): the default guess keeps a level camera 1 m
    up, and the person lying on the floor of a wall camera is not found; the depth floor finds them."""
    sc = WALL["wall/tune/fall/standing-sideways/fast-v30"]
    lying = [fr for fr in frames(sc) if fr.t >= sc.truth.t_impact + 0.5]
    assert lying

    def run(depth_floor: bool):
        det = FallDetector(FallsConfig(), "r1", fit_frame="camera")
        out = []
        for fr in lying:
            fr = replace(fr, t=fr.t - lying[0].t)
            if depth_floor:
                det.set_floor_plane(gravity_from_tilt(sc.camera.tilt), sc.camera.z)
            out += det.update(truth_result(fr, sc.camera), fr.landmarks, (sc.camera.width, sc.camera.height),
                              sc.camera.intrinsics)
        return out

    assert not [e for e in run(False) if e.state == "on_floor"]
    found = [e for e in run(True) if e.state == "on_floor"]
    assert found and found[0].extra["geometry"]["floor"] == "depth"
