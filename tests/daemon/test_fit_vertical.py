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
from posed.fitting.kinematics import body_angles_from_rotation, body_rotation
from posed.fitting.vertical import level_frame
from posed.landmarks import LandmarkFrame

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


def _seated(tilt_deg: float) -> np.ndarray:
    """A person seated upright (hips 86-88, lumbar 4 degrees) as a camera pitched down ``tilt_deg`` sees them."""
    from posed.bench import simulate as S

    level = S.pose("sit_chair", 30.0)
    r = level_frame(gravity_from_tilt(tilt_deg)) @ body_rotation(level.theta_bd, level.phi_bd, level.psi_bd)
    t, p, s = body_angles_from_rotation(r)
    return S.render(level.replace(theta_bd=t, phi_bd=p, psi_bd=s), dims=DIMS,
                    camera=S.LevelCamera(model="pinhole"))


@pytest.mark.parametrize("how", ["mount", "imu", "none"])
def test_the_stage_fits_a_seated_person_under_a_tilted_camera_with_the_down_it_has(how):
    from posed.bench import simulate as S

    cfg = _config(camera_tilt_deg=35.0) if how == "mount" else _config()
    stage = people_fit(lambda: Fitter(replace(cfg.fitting, body_height_m=1.6)), cfg)
    k = S.LevelCamera(model="pinhole").intrinsics((640, 480))
    lm = _seated(35.0)
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
