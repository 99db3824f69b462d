"""The least-squares residuals of the refinement (fitting.jacobian, fitting.penalties) and the torso
uprightness against plain NumPy references. The Jacobian itself is checked against finite differences in
test_kinematics.py."""

import math

import numpy as np
import pytest

from posed.fitting import forward_kinematics as FK
from posed.fitting import jacobian as JAC
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import BODY_LANDMARKS, body_rotation, landmarks_camera, rot_x, rot_y, rot_z
from posed.fitting.result import MODEL_VARIABLE_NAMES

DIMS = BodyDimensions.from_height(1.65)


def x_of(pose, gamma):
    return P.to_radians(np.array([gamma] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))


@pytest.mark.parametrize("perspective", [False, True])
def test_landmark_rows_match_reference(perspective):
    """Rows R_LM..: sqrt(w_i / sum w) (b_i - a_i T) with T the weighted least-squares translation."""
    from posed.bench import simulate as S

    cfg = FitConfig()
    cam = S.LevelCamera(model="pinhole", distance_m=3.0) if perspective else None
    truth = S.pose("bend_grab", 40.0)
    lm = S.render(truth, dims=DIMS, noise_px=3.0, seed=4, **({"camera": cam} if cam else {}))
    xy, w, _ = P.landmark_weights(lm, cfg)
    w[5] = 0.3
    intrinsics = cam.intrinsics((640, 480)) if cam else None
    frame = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS), intrinsics)
    d = frame.data
    obs = d[L.D_OBS:L.D_OBS + 2 * L.N_LM].reshape(L.N_LM, 2)
    h = DIMS.body_height_m
    rng = np.random.default_rng(5)
    for k in range(4):
        pose = truth if k == 0 else truth.replace(theta_sh_l=rng.uniform(-40, 120),
                                                  theta_kn_r=rng.uniform(0, 90),
                                                  psi_bd=truth.psi_bd + rng.normal(0, 20))
        gamma = 0.9 + 0.1 * k
        model = landmarks_camera(pose, DIMS)[list(BODY_LANDMARKS)]
        if perspective:
            fn = d[L.D_PROJ + L.PJ_FN_X:L.D_PROJ + L.PJ_FN_Y + 1]
            depth = fn[1] * h / gamma + model[:, 2]
            a = fn[None, :] / depth[:, None]
            b = obs + d[L.D_PROJ + L.PJ_OFF_X:L.D_PROJ + L.PJ_OFF_Y + 1] - a * model[:, :2]
        else:
            a = np.ones((L.N_LM, 2))
            b = obs - gamma * model[:, :2] / h
        t = (w[:, None] * a * b).sum(0) / (w[:, None] * a * a).sum(0)
        ref = np.sqrt(w / w.sum())[:, None] * (b - a * t)
        res = np.empty(JAC.n_residuals())
        JAC.residuals_jacobian(x_of(pose, gamma), d, res, np.empty((1, 1)), False)
        np.testing.assert_allclose(res[L.R_LM:L.R_LM + 2 * L.N_LM].reshape(L.N_LM, 2), ref, atol=1e-12)


def test_hinge_rows_match_reference():
    """Rows R_PEN.. (penalties of eqs. 9-11), R_LIM.. (joint limits) and R_PRIOR.. (pose prior)."""
    cfg = FitConfig(w_limit=0.5)
    xy = np.random.default_rng(0).normal(300, 50, (L.N_LM, 2))
    frame = P.pack(xy, np.ones(L.N_LM), DIMS, cfg, 200.0, rotation=True)   # every variable within its limits
    d = frame.data.copy()
    d[L.D_PRIOR] = 0.01
    d[L.D_PRIOR_MU:L.D_PRIOR_MU + L.N_VAR] = P.PRIOR_MU_RAD
    d[L.D_PRIOR_SIG:L.D_PRIOR_SIG + L.N_VAR] = P.PRIOR_SIG_RAD
    d[L.D_PRIOR_PARTNER:L.D_PRIOR_PARTNER + L.N_VAR] = P.PRIOR_PARTNER
    r = math.radians
    th = {"tr_flex": r(cfg.tr_flexion_min_deg), "tr_lat": r(cfg.tr_lateral_deg),
          "tr_twist": r(cfg.tr_twist_deg), "sh_flex": r(cfg.sh_flexion_min_deg),
          "sh_add": r(cfg.sh_adduction_max_deg), "hp_add": r(cfg.hp_adduction_max_deg)}
    rng = np.random.default_rng(8)
    for _ in range(50):
        x = rng.uniform(P.LIMIT_LO_RAD * 1.3, P.LIMIT_HI_RAD * 1.3)   # some outside the limits
        v = dict(zip(MODEL_VARIABLE_NAMES, x, strict=True))
        pen = [
            (cfg.w_sag_tr, max(0.0, th["tr_flex"] - v["theta_tr"])),
            (cfg.w_cor_tr, max(0.0, abs(v["phi_tr"]) - th["tr_lat"])),
            (cfg.w_tran_tr, max(0.0, abs(v["psi_tr"]) - th["tr_twist"])),
            *[(cfg.w_sag_sh, max(0.0, th["sh_flex"] - v[f"theta_sh_{s}"])) for s in "lr"],
            *[(cfg.w_cor_sh, max(0.0, v[f"phi_sh_{s}"] - th["sh_add"])) for s in "lr"],
            *[(cfg.w_cor_hp, max(0.0, v[f"phi_hp_{s}"] - th["hp_add"])) for s in "lr"],
        ]
        ref_pen = [math.sqrt(wt) * p for wt, p in pen]
        ref_lim = math.sqrt(cfg.w_limit) * np.maximum(0.0, np.maximum(P.LIMIT_LO_RAD - x, x - P.LIMIT_HI_RAD))
        partner = np.where(P.PRIOR_PARTNER >= 0, x[P.PRIOR_PARTNER.astype(int)], 0.0)
        sig = P.PRIOR_SIG_RAD
        ref_prior = np.where(sig > 0, 0.1 * (x - partner - P.PRIOR_MU_RAD) / np.where(sig > 0, sig, 1.0), 0.0)
        res = np.empty(JAC.n_residuals())
        JAC.residuals_jacobian(x, d, res, np.empty((1, 1)), False)
        np.testing.assert_allclose(res[L.R_PEN:L.R_PEN + L.N_PEN], ref_pen, atol=1e-12)
        np.testing.assert_allclose(res[L.R_LIM:L.R_LIM + L.N_VAR], ref_lim, atol=1e-12)
        np.testing.assert_allclose(res[L.R_PRIOR:L.R_PRIOR + L.N_VAR], ref_prior, atol=1e-12)
    assert L.N_RES == JAC.n_residuals() == L.R_DEPTH + L.N_LM


def test_torso_uprightness_matches_reference():
    rng = np.random.default_rng(9)
    for _ in range(50):
        tbd, pbd, sbd, ttr, ptr, s_tr = rng.uniform(-120, 120, 6)
        r = body_rotation(tbd, pbd, sbd) @ rot_y(math.radians(ttr)) @ rot_x(-math.radians(ptr)) \
            @ rot_z(math.radians(s_tr))
        x = np.zeros(L.N_VAR)
        angles = np.radians([tbd, pbd, sbd, ttr, ptr, s_tr])
        x[[L.X_TBD, L.X_PBD, L.X_SBD, L.X_TTR, L.X_PTR, L.X_STR]] = angles
        # the torso's z axis (up along the spine) against camera up (-y), clipped at 0
        assert FK.torso_uprightness(x) == pytest.approx(max(0.0, -r[1, 2]), abs=1e-12)


def _central_differences(x, d, h=1e-6):
    """d res / d x (N_RES x N_VAR) by central differences of JAC.residuals_jacobian's residuals."""
    out = np.empty((L.N_RES, L.N_VAR))
    for k in range(L.N_VAR):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        rp, rm = np.empty(L.N_RES), np.empty(L.N_RES)
        JAC.residuals_jacobian(xp, d, rp, np.empty((1, 1)), False)
        JAC.residuals_jacobian(xm, d, rm, np.empty((1, 1)), False)
        out[:, k] = (rp - rm) / (2 * h)
    return out


def test_depth_rows_match_reference_and_finite_differences():
    """Rows R_DEPTH..: w_i (Z_i - target_i), Z_i landmark i's camera-axes depth relative to the mid-hip (the
    NumPy model's landmarks_camera), and their Jacobian row against central finite differences."""
    cfg = FitConfig()
    xy = np.random.default_rng(1).normal(300, 50, (L.N_LM, 2))
    d = P.pack(xy, np.ones(L.N_LM), DIMS, cfg, 200.0).data.copy()
    rng = np.random.default_rng(3)
    d[L.D_DEPTH:L.D_DEPTH + L.N_LM] = rng.normal(0.0, 0.2, L.N_LM)
    d[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = rng.uniform(0.0, 30.0, L.N_LM)
    from posed.bench import simulate as S

    pose = S.pose("walk_left_forward", 35.0)
    x = x_of(pose, 1.0)
    z = landmarks_camera(pose, DIMS)[list(BODY_LANDMARKS), 2]
    res = np.empty(L.N_RES)
    jac = np.empty((L.N_RES, L.N_VAR))
    JAC.residuals_jacobian(x, d, res, jac, True)
    w, target = d[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM], d[L.D_DEPTH:L.D_DEPTH + L.N_LM]
    np.testing.assert_allclose(res[L.R_DEPTH:], w * (z - target), atol=1e-10)
    np.testing.assert_allclose(jac[L.R_DEPTH:], _central_differences(x, d)[L.R_DEPTH:], atol=1e-5)


def test_flexion_rows_match_reference_and_finite_differences():
    """Rows R_FLEX..: w_h (x_k - flex_h) for the hinge k = FLEX_VARS[h] (zero where w_h is 0), and their
    Jacobian against central finite differences; the normal equations count them."""
    cfg = FitConfig()
    xy = np.random.default_rng(1).normal(300, 50, (L.N_LM, 2))
    d = P.pack(xy, np.ones(L.N_LM), DIMS, cfg, 200.0).data.copy()
    rng = np.random.default_rng(4)
    x = rng.uniform(0.1, 1.5, L.N_VAR)
    res, jac = np.empty(L.N_RES), np.empty((L.N_RES, L.N_VAR))
    JAC.residuals_jacobian(x, d, res, jac, True)
    assert not res[L.R_FLEX:L.R_FLEX + L.N_FLEX].any() and not jac[L.R_FLEX:L.R_FLEX + L.N_FLEX].any()
    flex, w = rng.uniform(0.0, 2.0, L.N_FLEX), np.array([3.0, 0.0, 1.5, 7.0])
    d[L.D_FLEX:L.D_FLEX + L.N_FLEX], d[L.D_FLEX_W:L.D_FLEX_W + L.N_FLEX] = flex, w
    JAC.residuals_jacobian(x, d, res, jac, True)
    rows = slice(L.R_FLEX, L.R_FLEX + L.N_FLEX)
    np.testing.assert_allclose(res[rows], w * (x[list(L.FLEX_VARS)] - flex), atol=1e-12)
    np.testing.assert_allclose(jac[rows], _central_differences(x, d)[rows], atol=1e-6)
    a, g = np.empty((L.N_VAR, L.N_VAR)), np.empty(L.N_VAR)
    refine.normal_equations(jac, res, a, g, np.empty(L.N_VAR, dtype=np.int64))
    np.testing.assert_allclose(a, jac.T @ jac, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(g, jac.T @ res, rtol=1e-9, atol=1e-9)


def test_residuals_into_and_jacobian_into_reuse_their_work():
    """JAC.residuals_into + JAC.jacobian_into (the refinement's allocation-free pair) on one work tuple,
    alternating pinhole and orthographic frames, with and without depth rows and the prior: bit for bit
    JAC.residuals_jacobian (checked against the NumPy references here and finite differences in
    test_kinematics.py), whose work arrays are fresh."""
    from posed.bench import simulate as S

    cfg = FitConfig()
    cam = S.LevelCamera(model="pinhole", distance_m=3.0)
    truth = S.pose("bend_grab", 40.0)
    lm = S.render(truth, dims=DIMS, noise_px=3.0, seed=4, camera=cam)
    xy, w, _ = P.landmark_weights(lm, cfg)
    rng = np.random.default_rng(6)
    work = JAC.empty_work()
    for k in range(8):
        intrinsics = cam.intrinsics((640, 480)) if k % 2 == 0 else None
        d = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS), intrinsics).data.copy()
        if k % 4 < 2:
            d[L.D_DEPTH:L.D_DEPTH + L.N_LM] = rng.normal(0.0, 0.2, L.N_LM)
            d[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = rng.uniform(0.0, 3.0, L.N_LM)
            d[L.D_PRIOR] = 0.5
            d[L.D_PRIOR_SIG:L.D_PRIOR_SIG + L.N_VAR] = P.PRIOR_SIG_RAD
            d[L.D_PRIOR_PARTNER:L.D_PRIOR_PARTNER + L.N_VAR] = P.PRIOR_PARTNER
        x = x_of(truth, 1.0) + rng.normal(0.0, 0.3, L.N_VAR) * (np.arange(L.N_VAR) > 0)
        res, jac = np.empty(L.N_RES), np.empty((L.N_RES, L.N_VAR))
        JAC.residuals_into(x, d, res, work)
        JAC.jacobian_into(x, d, jac, work)
        ref_res, ref_jac = np.empty(L.N_RES), np.empty((L.N_RES, L.N_VAR))
        JAC.residuals_jacobian(x, d, ref_res, ref_jac, True)
        assert np.array_equal(res, ref_res) and np.array_equal(jac, ref_jac)
