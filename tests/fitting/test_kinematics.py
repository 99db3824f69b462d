"""The humanoid model: the numba forward kinematics against the plain NumPy reference, sign conventions,
the unobservable pelvis tilt, the analytic Jacobian against finite differences."""

import math

import numpy as np
import pytest

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import loss as LOSS
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import (
    BODY_LANDMARKS,
    Pose,
    body_angles_from_rotation,
    body_rotation,
    landmarks_camera,
    skeleton,
)
from posed.fitting.result import JOINT_ANGLE_NAMES, MODEL_VARIABLE_NAMES
from tests.fitting.jacobian_check import assert_jacobian_matches_finite_differences, rendered_frame

DIMS = BodyDimensions.from_height(1.72)
FIXED = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")
# kernel point rows of the reference's MediaPipe indices
ROWS = {**{i: r for r, i in enumerate(BODY_LANDMARKS)}, 29: L.P_HEEL_L, 30: L.P_HEEL_R, 31: L.P_TOE_L,
        32: L.P_TOE_R}


def random_pose(rng) -> Pose:
    joints = {name: rng.uniform(-60, 60) for name in JOINT_ANGLE_NAMES}
    for name in ("theta_kn_l", "theta_kn_r", "theta_el_l", "theta_el_r"):
        joints[name] = rng.uniform(0, 140)
    return Pose(joints, theta_bd=rng.uniform(-100, 100), phi_bd=rng.uniform(-80, 80), psi_bd=rng.uniform(-180, 180),
                psi_sh_l=rng.uniform(-90, 70), psi_sh_r=rng.uniform(-90, 70))


def kernel_data(pose: Pose, dims=DIMS) -> tuple[np.ndarray, np.ndarray]:
    data = np.zeros(L.D_SIZE)
    data[L.D_DIMS:L.D_DIMS + L.N_DIMS] = dims.as_array()
    data[L.D_FIXED:L.D_FIXED + L.N_FIXED] = np.radians([pose.angle(n) for n in FIXED])
    x = P.to_radians(np.array([1.0] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))
    return data, x


def test_kernel_forward_kinematics_matches_numpy_reference():
    rng = np.random.default_rng(3)
    for _ in range(25):
        pose = random_pose(rng)
        data, x = kernel_data(pose)
        pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points(x, data, pts_b, pts_c)
        sk = skeleton(pose, DIMS)
        cam = landmarks_camera(pose, DIMS)
        for idx, row in ROWS.items():
            np.testing.assert_allclose(pts_b[row], sk.landmarks[idx], atol=1e-12)
            np.testing.assert_allclose(pts_c[row], cam[idx], atol=1e-12)
        np.testing.assert_allclose(pts_b[L.P_COM], sk.com, atol=1e-12)
        np.testing.assert_allclose(pts_b[L.P_HEAD], 0.5 * (sk.landmarks[7] + sk.landmarks[8]), atol=1e-12)


def test_incremental_loss_equals_fresh_evaluation():
    """The loss caches trig values and moved points between calls; every call must equal a fresh one."""
    rng = np.random.default_rng(4)
    pose = random_pose(rng)
    data, x = kernel_data(pose)
    data[L.D_W:L.D_W + 12] = 1.0
    data[L.D_OBS:L.D_OBS + 24] = rng.normal(0, 0.2, 24)
    data[L.D_LW + L.LW_COM] = 0.01
    data[L.D_LW + L.LW_CONTACT] = 0.06
    data[L.D_LW + L.LW_MARGIN] = 1.0
    data[L.D_LW + L.LW_COM_MODE] = L.COM_SUPPORT
    data[L.D_LW + L.LW_NULL] = 0.01
    data[L.D_LW + L.LW_PRIOR_UP] = 1.0
    work = FK.empty_work()
    for _ in range(200):
        k = rng.integers(0, L.N_VAR)
        x[k] += rng.normal(0, 0.3)
        cached = LOSS.pose_loss(x, data, work)
        fresh = LOSS.pose_loss(x, data, FK.empty_work())
        assert cached == pytest.approx(fresh, rel=1e-12, abs=1e-15)
    # new body dimensions invalidate the cache
    data[L.D_DIMS:L.D_DIMS + L.N_DIMS] = BodyDimensions.from_height(1.5).as_array()
    assert LOSS.pose_loss(x, data, work) == pytest.approx(LOSS.pose_loss(x, data, FK.empty_work()), rel=1e-12)


def test_body_angles_round_trip():
    rng = np.random.default_rng(5)
    for _ in range(50):
        t, p, s = rng.uniform(-170, 170), rng.uniform(-85, 85), rng.uniform(-175, 175)
        np.testing.assert_allclose(body_angles_from_rotation(body_rotation(t, p, s)), (t, p, s), atol=1e-9)


def test_vicon_signs_and_camera_axes():
    neutral = landmarks_camera(Pose(), DIMS)
    # facing the camera: the left shoulder on the image right, the head up (y down), feet down
    assert neutral[11, 0] > 0 > neutral[12, 0]
    assert neutral[0, 1] < neutral[11, 1] < neutral[23, 1] < neutral[27, 1]
    assert neutral[0, 2] < 0  # the nose is nearer the camera than the mid-hip
    ahead = -1.0  # the person's forward direction is toward the camera: -z

    def moved(name, value, idx, axis):
        return landmarks_camera(Pose({name: value}), DIMS)[idx, axis] - neutral[idx, axis]

    assert moved("theta_hp_l", 30, 25, 2) * ahead > 0          # hip flexion: knee forward
    assert moved("theta_kn_l", 30, 27, 2) * ahead < 0          # knee flexion: ankle backward
    assert moved("theta_sh_r", 30, 14, 2) * ahead > 0          # shoulder flexion: elbow forward
    assert moved("theta_el_r", 30, 16, 2) * ahead > 0          # elbow flexion: wrist forward
    assert moved("phi_hp_l", 20, 25, 0) < 0                    # left adduction: knee toward the midline
    assert moved("phi_hp_r", 20, 26, 0) > 0                    # right adduction: knee toward the midline
    assert moved("phi_sh_l", -30, 13, 0) > 0                   # left abduction: elbow outward (image right)
    assert moved("theta_tr", 30, 11, 2) * ahead > 0            # lumbar flexion: shoulders forward
    tilt = landmarks_camera(Pose(theta_bd=30), DIMS)
    assert (tilt[11, 2] - neutral[11, 2]) * ahead > 0          # forward tilt of the body
    left = landmarks_camera(Pose(phi_bd=30), DIMS)
    assert left[11, 0] > neutral[11, 0] and left[11, 1] > neutral[11, 1]  # left tilt: left shoulder drops
    turn = landmarks_camera(Pose(psi_bd=30), DIMS)
    assert turn[11, 2] > neutral[11, 2]                        # left turn: the left shoulder moves away


def test_pelvis_tilt_is_exactly_unobservable():
    """(theta_bd + d, theta_tr - d, theta_hp + d): same landmarks, centre of mass and feet."""
    rng = np.random.default_rng(6)
    for _ in range(10):
        pose = random_pose(rng)
        d = rng.uniform(-40, 40)
        other = pose.replace(theta_bd=pose.theta_bd + d, theta_tr=pose.joints["theta_tr"] - d,
                             theta_hp_l=pose.joints["theta_hp_l"] + d, theta_hp_r=pose.joints["theta_hp_r"] + d)
        np.testing.assert_allclose(landmarks_camera(other, DIMS), landmarks_camera(pose, DIMS), atol=1e-12)
        a, b = skeleton(pose, DIMS), skeleton(other, DIMS)
        np.testing.assert_allclose(body_rotation(other.theta_bd, other.phi_bd, other.psi_bd) @ b.com,
                                   body_rotation(pose.theta_bd, pose.phi_bd, pose.psi_bd) @ a.com, atol=1e-12)


@pytest.mark.parametrize("perspective", [False, True])
def test_analytic_jacobian_matches_finite_differences(perspective):
    from posed.bench import simulate as S

    cfg = FitConfig(w_limit=0.5)
    rng = np.random.default_rng(7 + perspective)
    pose = S.pose("kneel", 35.0)
    frame = rendered_frame(pose, DIMS, cfg, perspective, weights={3: 0.4},   # a down-weighted landmark
                           fixed_deg=np.array([5, -3, 10, -8, 4, 2, -3, 1.0]))
    data = frame.data.copy()
    data[L.D_PRIOR] = 1e-4
    data[L.D_PRIOR_MU:L.D_PRIOR_MU + L.N_VAR] = P.PRIOR_MU_RAD
    data[L.D_PRIOR_SIG:L.D_PRIOR_SIG + L.N_VAR] = P.PRIOR_SIG_RAD
    data[L.D_PRIOR_PARTNER:L.D_PRIOR_PARTNER + L.N_VAR] = P.PRIOR_PARTNER
    for _ in range(4):
        x = P.to_radians(np.array([1.0] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]])) + rng.normal(0, 0.4, L.N_VAR)
        x[0] = 0.9 + 0.2 * rng.random()
        res = assert_jacobian_matches_finite_differences(x, data)
        # the landmark residuals are the kernel's 2D error: mean squared distance
        mse = float(np.sum(res[: 2 * L.N_LM] ** 2))
        work = FK.empty_work()
        assert math.isfinite(mse) and LOSS.pose_loss_terms(x, frame.data, work)[1] >= 0


def test_model_points_into_reuses_its_work_array():
    """FK.model_points_into on one work array across poses and bodies: the same points, bit for bit, as
    FK.model_points (checked against the NumPy model above) with a fresh one."""
    rng = np.random.default_rng(8)
    work = FK.empty_work()
    for k in range(10):
        data, x = kernel_data(random_pose(rng), BodyDimensions.from_height(1.5 + 0.05 * k))
        pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points_into(x, data, pts_b, pts_c, work)
        ref_b, ref_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points(x, data, ref_b, ref_c)
        assert np.array_equal(pts_b, ref_b) and np.array_equal(pts_c, ref_c)
