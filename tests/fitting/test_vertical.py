"""The fit's down given by gravity (fitting.vertical): the level frame itself, the kernels with a level frame
against the NumPy reference and finite differences, and what it is for: a person seated under a camera tilted
down reads hips of 90 degrees, not 90 minus the tilt."""


import numpy as np
import pytest

from posed.falls.features import gravity_from_tilt
from posed.fitting import FitConfig, Fitter
from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import loss as LOSS
from posed.fitting import orientation as O
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.kinematics import Pose, body_angles_from_rotation, body_rotation, landmarks_camera
from posed.fitting.result import MODEL_VARIABLE_NAMES
from posed.fitting.vertical import camera_body_angles, level_data, level_frame, reexpress
from tests.fitting.jacobian_check import assert_jacobian_matches_finite_differences, rendered_frame
from tests.fitting.seated_scene import seated_under

DIMS = BodyDimensions.from_height(1.72)
FIXED = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")


def kernel_x(pose: Pose) -> np.ndarray:
    return P.to_radians(np.array([1.0] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))


def kernel_data(pose: Pose, r_cl) -> np.ndarray:
    data = np.zeros(L.D_SIZE)
    data[L.D_DIMS:L.D_DIMS + L.N_DIMS] = DIMS.as_array()
    data[L.D_FIXED:L.D_FIXED + L.N_FIXED] = np.radians([pose.angle(n) for n in FIXED])
    data[L.D_LEVEL:L.D_LEVEL + 10] = level_data(r_cl)
    return data


def random_pose(rng) -> Pose:
    from posed.fitting.result import JOINT_ANGLE_NAMES

    joints = {name: rng.uniform(-50, 50) for name in JOINT_ANGLE_NAMES}
    return Pose(joints, theta_bd=rng.uniform(-80, 80), phi_bd=rng.uniform(-60, 60), psi_bd=rng.uniform(-180, 180))


def test_the_level_frame_of_a_level_camera_is_none_and_of_a_tilted_one_puts_y_along_gravity():
    assert level_frame(None) is None
    assert level_frame((0.0, 9.81, 0.0)) is None
    for tilt, roll in ((35.0, 0.0), (12.0, -7.0), (-20.0, 30.0), (0.0, 90.0)):
        g = np.array(gravity_from_tilt(tilt, roll))
        r = level_frame(3.0 * g)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) == pytest.approx(1.0)
        np.testing.assert_allclose(r[:, 1], g, atol=1e-12)     # y_L is down
        # x_L is the camera's x made level: in the plane of the camera's x and gravity (no heading added)
        assert float(r[:, 0] @ np.cross((1.0, 0.0, 0.0), g)) == pytest.approx(0.0, abs=1e-12)
    # a camera tilted down: its x axis is level, so x_L is the camera's x
    np.testing.assert_allclose(level_frame(gravity_from_tilt(35.0))[:, 0], (1.0, 0.0, 0.0), atol=1e-12)


@pytest.mark.parametrize("bad", [(0.0, 0.0, 0.0), (np.nan, 1.0, 0.0), (1.0, 2.0), "down"])
def test_a_bad_gravity_is_refused_with_what_is_wrong(bad):
    with pytest.raises(ValueError, match="gravity must be 3 finite numbers"):
        level_frame(bad)


def test_kernel_points_with_a_level_frame_are_the_reference_turned_by_it():
    rng = np.random.default_rng(11)
    for _ in range(10):
        pose = random_pose(rng)
        r_cl = level_frame(gravity_from_tilt(rng.uniform(-40, 40), rng.uniform(-30, 30)))
        pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points(kernel_x(pose), kernel_data(pose, r_cl), pts_b, pts_c)
        ref = landmarks_camera(pose, DIMS) @ r_cl.T     # the body angles are taken against the level frame
        for row, idx in enumerate((11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)):
            np.testing.assert_allclose(pts_c[row], ref[idx], atol=1e-12)
        # the same body through the camera's own angles (fitting.vertical.camera_body_angles)
        x_cam = camera_body_angles(kernel_x(pose), r_cl)
        cam_b, cam_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points(x_cam, kernel_data(pose, None), cam_b, cam_c)
        np.testing.assert_allclose(cam_c, pts_c, atol=1e-9)


def test_a_changed_level_frame_moves_the_cached_points():
    """The loss's work array caches rotated points: a new level frame with the same angles must move them."""
    pose = random_pose(np.random.default_rng(5))
    x = kernel_x(pose)
    work = FK.empty_work()
    a = kernel_data(pose, None)
    b = kernel_data(pose, level_frame(gravity_from_tilt(30.0)))
    for data in (a, b, a):
        LOSS.pose_loss(x, data, work)
        fresh = FK.empty_work()
        LOSS.pose_loss(x, data, fresh)
        np.testing.assert_array_equal(work[L.W_PTS_C:L.W_PTS_C + L.N_POINTS], fresh[L.W_PTS_C:L.W_PTS_C + L.N_POINTS])


def test_the_prior_and_the_centre_of_mass_measure_against_the_level_frame():
    """Both terms read the body in the level frame: with the level frame given they equal, for the same
    angles, what a level camera gives (only the projection, the 2D term, differs)."""
    rng = np.random.default_rng(8)
    cfg = FitConfig()
    base = P.pack(np.zeros((12, 2)) + 0.1 * np.arange(24).reshape(12, 2), np.ones(12), DIMS, cfg, 100.0).data
    for mode in (L.COM_FEET, L.COM_SUPPORT):
        for _ in range(8):
            pose = random_pose(rng)
            x = kernel_x(pose)
            flat = base.copy()
            flat[L.D_LW + L.LW_COM_MODE] = mode
            flat[L.D_LW + L.LW_COM] = 1.0
            flat[L.D_LW + L.LW_NULL] = 1.0
            lev = flat.copy()
            lev[L.D_LEVEL:L.D_LEVEL + 10] = level_data(level_frame(gravity_from_tilt(rng.uniform(5, 45), rng.uniform(-20, 20))))
            t_flat = LOSS.pose_loss_terms(x, flat, FK.empty_work())
            t_lev = LOSS.pose_loss_terms(x, lev, FK.empty_work())
            assert t_lev[2] == pytest.approx(t_flat[2], abs=1e-12)   # centre of mass over the support
            assert t_lev[5] == pytest.approx(t_flat[5], abs=1e-12)   # the pelvis-tilt prior
            assert t_lev[1] != pytest.approx(t_flat[1])               # the 2D error sees the turned body


@pytest.mark.parametrize("perspective", [False, True])
def test_analytic_jacobian_with_a_level_frame_matches_finite_differences(perspective):
    from posed.bench import simulate as S

    cfg = FitConfig(w_limit=0.5)
    rng = np.random.default_rng(17 + perspective)
    pose = S.pose("sit_chair", 35.0)
    frame = rendered_frame(pose, DIMS, cfg, perspective, level=level_data(level_frame(gravity_from_tilt(28.0, 9.0))))
    for _ in range(3):
        x = kernel_x(pose) + rng.normal(0, 0.3, L.N_VAR)
        x[0] = 0.9 + 0.2 * rng.random()
        assert_jacobian_matches_finite_differences(x, frame.data)


def test_orientation_seeds_with_a_level_frame_are_the_camera_seeds_turned_into_it():
    from posed.fitting.warmup import warmup_landmarks

    cfg = FitConfig()
    lm = warmup_landmarks(DIMS)
    xy, w, _ = P.landmark_weights(lm, cfg)
    frame = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS))
    lo, hi = np.full(L.N_VAR, -10.0), np.full(L.N_VAR, 10.0)   # no clipping
    r_cl = level_frame(gravity_from_tilt(30.0, -10.0))
    obs = frame.data[L.D_OBS:L.D_OBS + 24]
    cam, lev = np.empty((O.MAX_SEEDS, L.N_VAR)), np.empty((O.MAX_SEEDS, L.N_VAR))
    args = (obs, frame.weights, DIMS.body_height_m, DIMS.hip_half_m, DIMS.shoulder_half_m, DIMS.trunk_m, lo, hi)
    n = O.orientation_seeds_into(*args, np.zeros(10), cam)
    assert O.orientation_seeds_into(*args, level_data(r_cl), lev) == n > 0
    for a, b in zip(cam[:n], lev[:n], strict=True):
        r_cb = body_rotation(*np.degrees([a[L.X_TBD], a[L.X_PBD], a[L.X_SBD]]))
        want = body_angles_from_rotation(r_cl.T @ r_cb)
        np.testing.assert_allclose(np.degrees([b[L.X_TBD], b[L.X_PBD], b[L.X_SBD]]), want, atol=1e-9)


def test_reexpressed_state_is_the_same_body_in_the_camera():
    rng = np.random.default_rng(2)
    pose = random_pose(rng)
    x = kernel_x(pose)
    a, b = level_frame(gravity_from_tilt(20.0)), level_frame(gravity_from_tilt(33.0, 5.0))
    y = reexpress(x, a, b)
    np.testing.assert_allclose(camera_body_angles(y, b), camera_body_angles(x, a), atol=1e-9)
    np.testing.assert_allclose(camera_body_angles(reexpress(x, a, None), None), camera_body_angles(x, a),
                               atol=1e-9)


def test_a_person_seated_under_a_tilted_camera_reads_seated_hips_given_gravity():
    lm, k, g, seen = seated_under(35.0, DIMS)
    fitter = Fitter(FitConfig(body_height_m=DIMS.body_height_m))
    given = fitter.fit(lm, 0, 0.0, (640, 480), "image", k, gravity=g)
    fitter.reset()
    camera = fitter.fit(lm, 0, 0.0, (640, 480), "image", k)
    assert given.ok and camera.ok
    a, c = given.joint_angles_deg, camera.joint_angles_deg
    assert abs(a["theta_hp_l"] - 88) < 5 and abs(a["theta_hp_r"] - 86) < 5 and abs(a["theta_tr"] - 4) < 5
    assert c["theta_hp_l"] < 70 and c["theta_tr"] > 20        # the camera's own down: the tilt went to the lumbar
    assert given.extra["vertical"] == "gravity" and "vertical" not in camera.extra
    np.testing.assert_allclose(given.extra["down"], g, atol=1e-5)     # the unit down it used, camera axes
    # reported against the camera, as without gravity: the body angles of the body the camera saw
    assert given.variables["theta_bd"] == pytest.approx(seen.theta_bd, abs=5)
    for name, p in given.joints_3d.items():
        assert np.allclose(p, camera.joints_3d[name], atol=0.05), name


def test_video_mode_keeps_the_body_when_gravity_arrives_mid_track():
    """An IMU's first reading after some frames: the previous solution is re-expressed, not read in a new
    frame, so the next frame still tracks the same body."""
    lm, k, g, _ = seated_under(25.0, DIMS)
    fitter = Fitter(FitConfig(body_height_m=DIMS.body_height_m))
    first = fitter.fit(lm, 0, 0.0, (640, 480), "video", k)
    second = fitter.fit(lm, 1, 0.1, (640, 480), "video", k, gravity=g)
    assert first.ok and second.ok and second.extra["mode"] == "video"
    assert abs(second.joint_angles_deg["theta_hp_l"] - 88) < 6
    for name, p in second.joints_3d.items():
        assert np.allclose(p, first.joints_3d[name], atol=0.05), name
