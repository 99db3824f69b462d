"""The loss of section 4.2: each numba term against a plain NumPy reference."""

import math

import numpy as np
import pytest

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import loss as LOSS
from posed.fitting import penalties as PEN
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import BODY_LANDMARKS, Pose, landmarks_camera, skeleton, to_camera
from posed.fitting.result import MODEL_VARIABLE_NAMES

DIMS = BodyDimensions.from_height(1.6)


def ref_mpjpe(obs, model, w):
    """Eq. (7) with the weighted centroids aligned."""
    t = (w[:, None] * (obs - model)).sum(0) / w.sum()
    return float((w * np.linalg.norm(obs - model - t, axis=1)).sum() / w.sum())


def ref_comd(pose: Pose, cfg: FitConfig):
    """CoM deviation (docs/body-model.md, eq. 8) from the NumPy model, camera axes (gravity +y)."""
    cam = landmarks_camera(pose, DIMS)
    com = to_camera(skeleton(pose, DIMS).com, pose)
    leg = DIMS.leg_m
    contact = cfg.com_contact * DIMS.body_height_m
    head = 0.5 * (cam[7] + cam[8])
    if cfg.com_mode == "feet":
        pts = cam[[29, 30, 31, 32]]
        on = pts[:, 1] >= pts[:, 1].max() - contact
        centre = pts[on][:, [0, 2]].mean(0)
        return float(np.linalg.norm(com[[0, 2]] - centre) / leg)
    idx = [29, 30, 31, 32, 25, 26, 23, 24, 15, 16, 13, 14, 11, 12]
    pts = np.vstack([cam[idx], head])
    floor = pts[:, 1].max() - contact
    on = pts[:, 1] >= floor
    on[6] |= cam[23, 1] >= cam[25, 1] - contact  # a seat under the hips
    on[7] |= cam[24, 1] >= cam[26, 1] - contact
    lo, hi = pts[on][:, [0, 2]].min(0), pts[on][:, [0, 2]].max(0)
    centre, half_diagonal = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    dev = np.linalg.norm(com[[0, 2]] - centre) - cfg.com_margin * half_diagonal
    return max(0.0, float(dev)) / leg


def frame_for(pose, cfg, noise=0.0, seed=0):
    from posed.bench import simulate as S

    lm = S.render(pose, dims=DIMS, noise_px=noise, seed=seed)
    xy, w, _ = P.landmark_weights(lm, cfg)
    return P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS))


def x_of(pose, gamma=1.0):
    return P.to_radians(np.array([gamma] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))


@pytest.mark.parametrize("name", ["walk_left_forward", "sit_chair", "lying_side", "kneel"])
@pytest.mark.parametrize("mode", ["feet", "support"])
def test_loss_terms_match_reference(name, mode):
    from posed.bench import simulate as S

    cfg = FitConfig(com_mode=mode)
    truth = S.pose(name, 25.0)
    frame = frame_for(truth, cfg, noise=3.0, seed=2)
    rng = np.random.default_rng(1)
    for k in range(5):
        pose = truth if k == 0 else truth.replace(theta_hp_l=truth.joints["theta_hp_l"] + rng.normal(0, 15),
                                                  phi_sh_r=rng.normal(0, 20), phi_hp_l=rng.normal(5, 15), theta_tr=rng.normal(10, 30),
                                                  psi_bd=truth.psi_bd + rng.normal(0, 20))
        gamma = 1.0 + 0.05 * k
        x = x_of(pose, gamma)
        total, mp, comd, sym, pen, null = LOSS.pose_loss_terms(x, frame.data, FK.empty_work())
        obs = frame.data[L.D_OBS:L.D_OBS + 24].reshape(12, 2)
        model = gamma * landmarks_camera(pose, DIMS)[list(BODY_LANDMARKS), :2] / DIMS.body_height_m
        assert mp == pytest.approx(ref_mpjpe(obs, model, frame.weights), rel=1e-9, abs=1e-12)
        assert comd == pytest.approx(ref_comd(pose, cfg), rel=1e-9, abs=1e-12)
        j = pose.joints
        assert sym == pytest.approx(math.radians(abs(j["theta_hp_l"] - j["theta_hp_r"])
                                                 + abs(j["theta_kn_l"] - j["theta_kn_r"])), rel=1e-9)
        r = math.radians
        ref_pen = (cfg.w_sag_tr * max(0, r(cfg.tr_flexion_min_deg) - r(j["theta_tr"]))
                   + cfg.w_cor_tr * max(0, abs(r(j["phi_tr"])) - r(cfg.tr_lateral_deg))
                   + cfg.w_tran_tr * max(0, abs(r(j["psi_tr"])) - r(cfg.tr_twist_deg))
                   + cfg.w_sag_sh * sum(max(0, r(cfg.sh_flexion_min_deg) - r(j[f"theta_sh_{s}"])) for s in "lr")
                   + cfg.w_cor_sh * sum(max(0, r(j[f"phi_sh_{s}"]) - r(cfg.sh_adduction_max_deg)) for s in "lr")
                   + cfg.w_cor_hp * sum(max(0, r(j[f"phi_hp_{s}"]) - r(cfg.hp_adduction_max_deg)) for s in "lr"))
        assert pen == pytest.approx(ref_pen, rel=1e-9, abs=1e-15)
        assert total == pytest.approx(mp + cfg.w_com * comd + cfg.w_sym * sym + pen + cfg.w_null * null, rel=1e-12)


def test_penalty_functions_eqs_9_to_11():
    assert PEN.p_sn(-0.3, -0.2) == pytest.approx(0.1) and PEN.p_sn(0.0, -0.2) == 0.0
    assert PEN.p_sp(0.5, 0.2) == pytest.approx(0.3) and PEN.p_sp(0.1, 0.2) == 0.0
    assert PEN.p_d(-0.5, -0.2, 0.2) == pytest.approx(0.3) and PEN.p_d(0.4, -0.2, 0.2) == pytest.approx(0.2)
    assert PEN.p_d(0.0, -0.2, 0.2) == 0.0


def test_truth_has_zero_2d_error_and_stable_poses_zero_com_deviation():
    from posed.bench import simulate as S

    cfg = FitConfig()
    for name in S.PAPER_POSES + S.FLOOR_POSES:
        pose = S.pose(name, 30.0)
        frame = frame_for(pose, cfg)
        gamma = S.FILL * 480 / (frame.ppm0 * DIMS.body_height_m)  # the render scale over the reference
        terms = LOSS.pose_loss_terms(x_of(pose, gamma), frame.data, FK.empty_work())
        assert terms[1] < 1e-9, name
        if name in S.PAPER_POSES:
            # standing, sitting and kneeling people are balanced: the CoM lies over their support
            assert terms[2] == 0.0, name


def test_perspective_loss_is_exact_at_the_truth():
    from posed.bench import simulate as S
    from posed.bench.simulate import LevelCamera

    cfg = FitConfig()
    cam = LevelCamera(model="pinhole", distance_m=2.5)
    for name in ("bend_grab", "lying_back"):
        pose = S.pose(name, 35.0)
        lm = S.render(pose, dims=DIMS, camera=cam)
        xy, w, _ = P.landmark_weights(lm, cfg)
        ppm0 = P.reference_scale(xy, w, DIMS)
        frame = P.pack(xy, w, DIMS, cfg, ppm0, cam.intrinsics((640, 480)))
        # the mid-hip depth of the render: the lowest landmark on the floor, the hips 2.5 m away
        depth = 2.5
        gamma = cam.fy / depth / ppm0
        mp = LOSS.pose_loss_terms(x_of(pose, gamma), frame.data, FK.empty_work())[1]
        assert mp < 1e-9, name
