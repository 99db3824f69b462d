"""Which way is down for the fitting stage (daemon.stages.fit.frame_gravity, mount_gravity; fitting.vertical):
the frame's own IMU gravity, else its depth floor's down, else a measured mount's tilt and roll, else none; and the stage's fit of a person
seated under a tilted camera with each."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from posed.daemon.config.schema import Config
from posed.daemon.stages.fit import frame_gravity, mount_gravity, people_fit
from posed.falls.features import gravity_from_tilt
from posed.fitting import Fitter
from posed.fitting.body import BodyDimensions
from posed.landmarks import LandmarkFrame
from tests.fitting.seated_scene import seated_under

DIMS = BodyDimensions.from_height(1.6)


def _config(**falls) -> Config:
    c = Config()
    return replace(c, falls=replace(c.falls, **falls))


def test_a_measured_mount_gives_its_gravity_and_a_guess_none():
    assert mount_gravity(_config().falls) is None                          # nothing configured: the camera's +y
    np.testing.assert_allclose(mount_gravity(_config(camera_tilt_deg=35.0).falls), gravity_from_tilt(35.0))
    np.testing.assert_allclose(mount_gravity(_config(camera_tilt_deg=20.0, camera_roll_deg=-4.0,
                                                     camera_geometry="measured").falls),
                               gravity_from_tilt(20.0, -4.0))
    # a tilt only guessed (checked against the body by the detector) is not given to the fit
    assert mount_gravity(_config(camera_tilt_deg=35.0, camera_geometry="guess").falls) is None


def test_the_frame_s_own_gravity_comes_first_and_a_malformed_one_falls_back():
    mount = gravity_from_tilt(35.0)
    imu = (0.0, 0.8, 0.6)
    assert frame_gravity(LandmarkFrame(0, 0.0, None, gravity=imu), mount) == pytest.approx(imu)
    assert frame_gravity(LandmarkFrame(0, 0.0, None), mount) is mount
    assert frame_gravity(LandmarkFrame(0, 0.0, None, gravity=imu), mount, use_imu=False) is mount
    assert frame_gravity(LandmarkFrame(0, 0.0, None, extra={"gravity": [1.0, 2.0]}), None) is None
    # the floor plane the landmark stage measured in the depth image: after the IMU, before the mount
    floor = {"tries": 3, "misses": 0, "down": [0.0, 0.9, 0.436], "height_m": 1.2}
    assert frame_gravity(LandmarkFrame(0, 0.0, None, extra={"floor": floor}), mount) == pytest.approx(floor["down"])
    assert frame_gravity(LandmarkFrame(0, 0.0, None, gravity=imu, extra={"floor": floor}), mount) == \
        pytest.approx(imu)
    assert frame_gravity(LandmarkFrame(0, 0.0, None, extra={"floor": floor}), mount, use_floor=False) is mount
    # a floor fitted no plane yet (only its counters), or a malformed one: the mount's
    assert frame_gravity(LandmarkFrame(0, 0.0, None, extra={"floor": {"tries": 1, "misses": 1}}), mount) is mount
    assert frame_gravity(LandmarkFrame(0, 0.0, None, extra={"floor": {"down": [0, 0, 0]}}), mount) is mount


@pytest.mark.parametrize("how", ["mount", "imu", "none"])
def test_the_stage_fits_a_seated_person_under_a_tilted_camera_with_the_down_it_has(how):
    from posed.bench import simulate as S

    cfg = _config(camera_tilt_deg=35.0) if how == "mount" else _config()
    stage = people_fit(lambda: Fitter(replace(cfg.fitting, body_height_m=1.6)), cfg)
    k = S.LevelCamera(model="pinhole").intrinsics((640, 480))
    lm = seated_under(35.0, DIMS)[0]
    imu = tuple(gravity_from_tilt(35.0)) if how == "imu" else None
    hips = []
    for seq in range(5):
        result, others = stage.fit(LandmarkFrame(seq, 0.1 * seq, lm, gravity=imu), 0.1 * seq, (640, 480), k)
        assert result.ok and others == ()
        assert result.extra.get("vertical") == (None if how == "none" else "gravity")
        hips.append(result.joint_angles_deg["theta_hp_l"])
    if how == "none":
        assert max(hips) < 70          # the camera's +y as down: the tilt read as lumbar flexion
    else:
        assert all(math.isclose(h, 88.0, abs_tol=5.0) for h in hips)


def test_the_kept_geometry_is_read_again_only_every_save_period(tmp_path):
    import json

    from posed.daemon.stages.fit import KeptDown
    from posed.falls.camera_geometry import CameraGeometry

    cfg = _config().falls
    path = tmp_path / "geometry.json"
    kept = KeptDown(cfg, path, every_s=30.0)
    assert kept.at(0.0) is None                                       # no file yet
    path.write_text(json.dumps(_learned(cfg, 22.0).state()))
    assert kept.at(10.0) is None                                      # not read again before 30 s
    np.testing.assert_allclose(kept.at(30.0), gravity_from_tilt(22.0), atol=1e-9)
    path.write_text(json.dumps(CameraGeometry(cfg).state()))         # nothing learned (a new guess)
    assert kept.at(5.0) is None                                       # the clock went back: read again


def _learned(cfg, tilt_deg: float):
    """A camera geometry that learned its down from a person standing ``tilt_deg`` off the level guess."""
    from posed.falls.camera_geometry import CameraGeometry

    geometry = CameraGeometry(cfg)
    for _ in range(30):
        geometry.observe_body_axis(-gravity_from_tilt(tilt_deg), 0.1)
    assert geometry.used()["gravity"] == "body"
    return geometry


@pytest.mark.timeout(300)
def test_posed_run_fits_with_the_geometry_the_detector_kept(tmp_path, shared_data):
    """``posed run`` on the real squat video's landmarks (no IMU, no depth, nothing configured) with a
    geometry file in the state dir from an earlier run that learned the camera 22 degrees down: every pose is
    fitted against that down (real processes, a Zenoh router on 127.0.0.1)."""
    import json

    from posed.daemon.stages.fall_watch import geometry_file
    from tests.daemon.replay_util import replay_to_end
    from tests.landmarks import flipped_squat

    source = flipped_squat.write(shared_data, tmp_path / "squat.landmarks.jsonl", flip=())
    c = _config()
    path = geometry_file(tmp_path / "state", replace(c.source, type="file", path=str(source)))
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(_learned(c.falls, 22.0).state()))
    poses = [p for p in replay_to_end(tmp_path, source, "kept", ("pose",))["pose"] if p["ok"]]
    assert len(poses) > 10
    for p in poses:
        assert p["vertical"] == "gravity", p["seq"]
        np.testing.assert_allclose(p["down"], gravity_from_tilt(22.0), atol=1e-4)
