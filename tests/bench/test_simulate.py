"""The simulator: landmark arrays in MediaPipe order with plausible non-body points, cameras, noise, motions."""

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.fitting import landmarks_camera


def test_six_paper_poses_and_floor_poses_render():
    assert S.PAPER_POSES == ("stand_arms_front", "stand_arms_up", "walk_left_forward", "bend_grab", "sit_chair",
                             "kneel")
    assert {"lying_back", "lying_front", "sitting_floor", "fallen_forward", "fallen_backward",
            "fallen_sideways"} <= set(S.FLOOR_POSES)
    for name in S.PAPER_POSES + S.FLOOR_POSES:
        lm = S.render(S.pose(name, 30.0))
        assert lm.shape == (33, 5) and np.isfinite(lm).all()
        assert (lm[:, 3] > 0.9).all(), f"{name} leaves the image"
    with pytest.raises(KeyError, match="unknown pose"):
        S.pose("handstand")


def test_mediapipe_order_and_face_feet_points():
    lm = S.render(S.pose("stand_arms_front", 0.0))
    x, y = lm[:, 0], lm[:, 1]
    assert x[11] > x[12] and x[23] > x[24]          # the subject's left on the image right
    assert y[0] < y[11] < y[23] < y[25] < y[27]     # nose, shoulder, hip, knee, ankle from the top
    assert y[2] < y[0] < y[9]                       # eyes above the nose above the mouth
    assert x[7] > x[0] > x[8]                       # ears on either side of the nose
    for heel, toe, ankle in ((29, 31, 27), (30, 32, 28)):
        assert y[heel] > y[ankle] and y[toe] > y[ankle]
    assert lm[31, 2] < lm[29, 2]                    # toes point toward the camera: nearer (z negative)
    # the floor: the lowest landmark of a standing body is at the same height for every pose's yaw
    assert S.render(S.pose("kneel", 10.0))[:, 1].max() == pytest.approx(y.max())


def test_noise_is_seeded_and_sized():
    pose = S.pose("sit_chair", 30.0)
    clean = S.render(pose)
    a = S.render(pose, noise_px=2.0, seed=5)
    assert np.array_equal(a, S.render(pose, noise_px=2.0, seed=5))
    assert not np.array_equal(a, S.render(pose, noise_px=2.0, seed=6))
    d = (a - clean)[:, :2]
    assert 1.5 < d.std() < 2.5 and np.all(a[:, 2:] == clean[:, 2:])


def test_cameras():
    pose = S.pose("walk_left_forward", 30.0)
    ortho = S.render(pose, camera=S.LevelCamera(px_per_m=150.0))
    cam = landmarks_camera(pose, S.body_dimensions(1.6))
    np.testing.assert_allclose(ortho[11, :2] - ortho[23, :2], 150.0 * (cam[11, :2] - cam[23, :2]), atol=1e-9)
    pin = S.render(pose, camera=S.LevelCamera(model="pinhole", fx=500, fy=500, distance_m=4.0))
    assert abs(np.hypot(*(pin[11, :2] - pin[12, :2])) - 125 * np.hypot(*(cam[11, :2] - cam[12, :2]))) < 8
    # the nearer shoulder looks wider apart from the mid-hip than in orthographic projection at the hip depth
    assert S.apparent_gamma(S.body_dimensions(1.6), (640, 480), S.LevelCamera(model="pinhole", distance_m=4.0)) == \
        pytest.approx(600 / 4.0 * 1.6 / 480)
    off = S.render(pose, placement=S.Placement(x_m=3.0))
    assert (off[:, 3] < 0.1).any()  # out of the image: low visibility
    with pytest.raises(ValueError):
        S.LevelCamera(model="fisheye")


def test_sequences_have_ground_truth():
    for name in S.SEQUENCE_NAMES:
        seq = S.sequence(name, 25.0)
        frames = S.render_sequence(seq, fps=10)
        assert len(frames) == int(seq.duration_s * 10) + 1
        t, lm, pose = frames[-1]
        assert t == pytest.approx(seq.duration_s) and lm.shape == (33, 5) and pose.psi_bd != 0
        if seq.is_fall:
            assert 0 < seq.impact_s < seq.duration_s and seq.on_floor_from_s is not None
            # the hips end near the floor: much lower in the image than when standing
            assert frames[-1][1][23, 1] - frames[0][1][23, 1] > 60
    # falls are fast, sitting down is not
    fall = S.sequence("fall_forward")
    assert fall.pose_at(2.0).theta_bd - fall.pose_at(1.5).theta_bd > 30
    sit = S.sequence("stand_to_sit")
    assert abs(sit.pose_at(2.5).theta_bd - sit.pose_at(1.0).theta_bd) < 1
    with pytest.raises(KeyError):
        S.sequence("moonwalk")


def test_ground_truth_result():
    dims = S.body_dimensions(1.75)
    pose = S.pose("bend_grab", 20.0)
    truth = S.ground_truth(pose, dims, gamma=0.6)
    assert truth.ok and truth.variables["gamma"] == 0.6 and truth.variables["psi_bd"] == 20.0
    assert truth.joints_3d["mid_hip"] == (0.0, 0.0, 0.0)
    assert np.hypot(*np.subtract(truth.joints_3d["left_hip"], truth.joints_3d["right_hip"])[:2]) <= 2 * dims.hip_half_m
