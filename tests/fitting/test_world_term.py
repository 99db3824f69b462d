"""BlazePose's world landmarks in the fit (fitting.world_term): their scale and depths as the depth term's
measurements, the fit choosing each limb's depth order with them, and a wrong world (the tracker on another
pose) not dragging the fit; the knees' and elbows' flexion they measure, folded into video mode's prior with a
heavy tail; off by config, never the source of ``root_cam_m``."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.fitting import BODY_LANDMARKS, FitConfig, Fitter
from posed.fitting import fitter as fitter_module
from posed.fitting import layout as L
from posed.fitting.world_term import (
    FLEXION_SIGMA_DEG,
    WORLD_SIGMA_M,
    WORLD_Z0_M,
    flexion_prior,
    flexion_rows,
    world_depths,
    world_flexion,
    world_scale,
)
from tests.fitting.test_depth_term import CASES, SIZE, flips, scene


def world_of(pts: np.ndarray, rng: np.random.Generator | None = None, sigma_z: float = 0.0,
             sigma_xy: float = 0.0) -> np.ndarray:
    """World landmarks (33 x 5) from camera-frame points: mid-hip-centred, the 12 body joints known, with
    normal errors of ``sigma_xy`` across the image and ``sigma_z`` in depth."""
    w = np.full((33, 5), np.nan)
    body = pts[list(BODY_LANDMARKS)] - 0.5 * (pts[23] + pts[24])
    if rng is not None:
        body = body + rng.normal(0.0, 1.0, body.shape) * np.array([sigma_xy, sigma_xy, sigma_z])
    w[list(BODY_LANDMARKS), :3] = body
    w[list(BODY_LANDMARKS), 3:] = 1.0
    return w


def test_the_scale_is_the_models_metres_per_world_metre():
    dims, _, _, pts = scene("walk_left_forward", 30.0)
    w = world_of(pts)
    assert world_scale(w, dims) == pytest.approx(1.0, abs=0.02)          # the scene is rendered with dims
    small = w.copy()
    small[:, :3] *= 0.8                                                    # BlazePose's body 20 % smaller
    assert world_scale(small, dims) == pytest.approx(1.25, abs=0.03)
    assert world_scale(np.full((33, 5), np.nan), dims) is None


def test_world_depths_follow_the_world_z_and_drop_what_the_image_drops():
    dims, _, _, pts = scene("bend_grab", 60.0)
    w = world_of(pts)
    w[15, 3] = 0.1                                                         # left wrist hardly visible
    d = world_depths(w, dims, visibility_drop=0.5)
    body = list(BODY_LANDMARKS)
    assert np.isnan(d[body.index(15)]) and np.isfinite(np.delete(d, body.index(15))).all()
    rel = d - WORLD_Z0_M
    true = pts[body, 2] - 0.5 * (pts[23, 2] + pts[24, 2])
    ok = np.isfinite(rel)
    np.testing.assert_allclose(rel[ok], true[ok] * world_scale(w, dims), atol=1e-9)
    assert world_depths(None, dims, 0.5) is None
    with pytest.raises(ValueError, match="world landmarks must be a"):
        world_depths(np.zeros((12, 3)), dims, 0.5)


def _fit(lm, k, world=None, cfg=None):
    return Fitter(cfg or FitConfig(body_height_m=1.6)).fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=k,
                                                           world=world)


def test_world_landmarks_resolve_the_limbs_depth_order_and_a_wrong_world_does_not_drag_the_fit():
    """World landmarks with BlazePose's depth error (the sigma the fit assumes) put fewer limbs on the wrong
    side in depth; the world of another pose (a gross failure) costs each landmark at most one robust unit."""
    rng = np.random.default_rng(11)
    totals = {"none": [0, 0], "world": [0, 0]}
    err = {"none": [], "wrong": []}
    for name, yaw in CASES:
        dims, camera, pose, pts = scene(name, yaw)
        lm = S.render(pose, dims=dims, camera=camera, image_size=SIZE, noise_px=2.0, seed=int(yaw) + 400)
        k = camera.intrinsics(SIZE)
        plain = _fit(lm, k)
        good = _fit(lm, k, world_of(pts, rng, WORLD_SIGMA_M / 2, 0.02))
        other = scene("sit_chair" if name != "sit_chair" else "walk_left_forward", yaw + 90.0)[3]
        wrong = _fit(lm, k, world_of(other))
        for key, r in (("none", plain), ("world", good)):
            b, n = flips(r, pts)
            totals[key][0] += b
            totals[key][1] += n
        truth = pts[list(BODY_LANDMARKS)] - 0.5 * (pts[23] + pts[24])
        for key, r in (("none", plain), ("wrong", wrong)):
            fitted = np.array([r.joints_3d[n] for n in list(r.joints_3d)[1:]])
            err[key].append(np.linalg.norm(fitted - truth, axis=1).mean())
    assert totals["world"][1] == totals["none"][1] > 20
    # the term's weight is the maximum-a-posteriori one (fitting.world_term): the 2 px landmarks (about 1 cm
    # at 3 m) still outweigh a 10 cm world depth except where the image cannot tell (measured: 9 of 74 without,
    # 6 with; with exact world landmarks 4)
    assert totals["none"][0] >= 5 and totals["world"][0] <= totals["none"][0] - 2, totals
    # a wrong world: the 2D landmarks still decide; on average no worse than a limb's depth mirror or two
    assert np.mean(err["wrong"]) - np.mean(err["none"]) < 0.03, (np.mean(err["wrong"]), np.mean(err["none"]))


def test_world_landmarks_are_off_by_config_and_never_place_the_person():
    dims, camera, pose, pts = scene("stand_arms_front", 30.0)
    lm = S.render(pose, dims=dims, camera=camera, image_size=SIZE, noise_px=2.0, seed=3)
    k = camera.intrinsics(SIZE)
    w = world_of(pts)
    plain = _fit(lm, k)
    off = _fit(lm, k, w, replace(FitConfig(body_height_m=1.6), world_landmarks=False))
    timing = {"fit_ms": 0, "udeas_ms": 0}
    assert off.to_json() | timing == plain.to_json() | timing
    on = _fit(lm, k, w)
    assert on.ok and "depth_inliers" not in on.extra          # root_cam_m from the size, as without depth
    assert on.root_cam_m is not None


def test_a_bad_world_array_is_a_clear_failure():
    lm = S.render(S.pose("stand_arms_front", 30.0))
    r = Fitter().fit(lm, 0, 0.0, SIZE, world=np.ones((33, 3)))
    assert not r.ok and "world must be 33 x [x, y, z, visibility, presence]" in r.reason


HINGES = {L.X_TKN_L: "theta_kn_l", L.X_TKN_R: "theta_kn_r", L.X_TEL_L: "theta_el_l", L.X_TEL_R: "theta_el_r"}


def test_world_flexion_is_each_hinges_angle_and_skips_what_is_not_known():
    for name in ("sit_chair", "walk_left_forward", "kneel"):
        _, _, pose, pts = scene(name, 40.0)
        got = {k: (math.degrees(a), math.degrees(s)) for k, a, s in world_flexion(world_of(pts), 0.5)}
        assert set(got) == set(HINGES)
        for k, (angle, spread) in got.items():
            assert angle == pytest.approx(pose.joints[HINGES[k]], abs=0.01), (name, HINGES[k])
            assert spread == FLEXION_SIGMA_DEG["knee" if "kn" in HINGES[k] else "elbow"]
    w = world_of(scene("sit_chair", 40.0)[3])
    w[15, 3] = 0.1                    # left wrist hardly visible: no left elbow
    w[26, :3] = w[24, :3]             # right knee on the hip: no right thigh, no right knee
    assert {k for k, _, _ in world_flexion(w, 0.5)} == {L.X_TKN_L, L.X_TEL_R}


def _product_reference(mu, sig, angle, s_w):
    """The product of N(mu, sig) and N(angle, s_w sqrt(1 + u^2)), u the distance in the combined spread."""
    s_eff = s_w * np.sqrt(1.0 + (angle - mu) ** 2 / (s_w ** 2 + sig ** 2))
    var = 1.0 / (1.0 / sig ** 2 + 1.0 / s_eff ** 2)
    return var * (mu / sig ** 2 + angle / s_eff ** 2), np.sqrt(var)


def test_flexion_prior_multiplies_the_two_densities_with_a_heavy_tail():
    rng = np.random.default_rng(3)
    for _ in range(50):
        mu, sig = rng.uniform(0.0, 2.0, L.N_VAR), rng.uniform(0.05, 1.0, L.N_VAR)
        flex = [(k, float(rng.uniform(0.0, 2.5)), float(rng.uniform(0.1, 0.6))) for k in (L.X_TKN_R, L.X_TEL_L)]
        m, s = mu.copy(), sig.copy()
        flexion_prior(m, s, flex)
        for k, angle, s_w in flex:
            ref_mu, ref_sig = _product_reference(mu[k], sig[k], angle, s_w)
            assert m[k] == pytest.approx(ref_mu, rel=1e-12) and s[k] == pytest.approx(ref_sig, rel=1e-12)
            assert s[k] < sig[k]                                           # a measurement always narrows
        untouched = [i for i in range(L.N_VAR) if i not in (L.X_TKN_R, L.X_TEL_L)]
        assert (m[untouched] == mu[untouched]).all() and (s[untouched] == sig[untouched]).all()

    def moved(angle, prior_deg):
        m, s = np.zeros(L.N_VAR), np.full(L.N_VAR, math.radians(prior_deg))
        flexion_prior(m, s, [(L.X_TKN_L, angle, math.radians(16.0))])
        return m[L.X_TKN_L]
    # a world angle near the prior pulls as a normal one would (within 2 %); one far from it in their combined
    # spread (BlazePose badly wrong) less and less: with a tight prior (60 fps: 8 degrees) 150 degrees away moves
    # it less than 60 away does, and that less than 30 away; with 10 fps's wide one (50) the pull only levels off
    gauss = math.radians(5.0) * (1 / 16.0 ** 2) / (1 / 50.0 ** 2 + 1 / 16.0 ** 2)
    assert moved(math.radians(5.0), 50.0) == pytest.approx(gauss, rel=0.02)
    assert moved(math.radians(150.0), 8.0) < moved(math.radians(60.0), 8.0) < moved(math.radians(30.0), 8.0)
    assert moved(math.radians(150.0), 50.0) < 2.0 * moved(math.radians(60.0), 50.0)


def test_flexion_rows_weigh_each_measured_hinge_with_a_heavy_tail():
    data = np.zeros(L.D_SIZE)
    x_ref = np.zeros(L.N_VAR)
    x_ref[L.X_TKN_R], x_ref[L.X_TEL_L] = 0.3, 1.0
    flex = [(L.X_TKN_R, 0.5, 0.28), (L.X_TEL_L, 2.5, 0.56)]
    flexion_rows(data, flex, 0.04, x_ref)
    for k, angle, s_w in flex:
        h = L.FLEX_VARS.index(k)
        u = (angle - x_ref[k]) / s_w
        assert data[L.D_FLEX + h] == angle
        assert data[L.D_FLEX_W + h] == pytest.approx(math.sqrt(0.04) / (s_w * math.sqrt(1.0 + u * u)), rel=1e-12)
    for k in (L.X_TKN_L, L.X_TEL_R):                                      # not measured: no row
        assert data[L.D_FLEX_W + L.FLEX_VARS.index(k)] == 0.0
    # the farther the measurement from the solution refined, the less it weighs (in spreads: 0.7 and 2.7)
    assert data[L.D_FLEX_W + L.FLEX_VARS.index(L.X_TEL_L)] * 0.56 < data[L.D_FLEX_W + L.FLEX_VARS.index(L.X_TKN_R)] * 0.28


def _hinge_errors(mode, rng, off_patch):
    """Noisy image landmarks (3 px) and world landmarks with 3 cm errors per joint, four frames of each scene
    in ``mode``: the hinges' mean error over the last three, with the world flexion and without it
    (``off_patch``: the fitter's name to replace with a no-op; the world depths used in both)."""
    err = {"off": [], "on": []}
    for name, yaw in CASES:
        dims, camera, pose, pts = scene(name, yaw)
        k = camera.intrinsics(SIZE)
        frames = [S.render(pose, dims=dims, camera=camera, image_size=SIZE, noise_px=3.0, seed=int(yaw) + 100 + i)
                  for i in range(4)]
        worlds = [world_of(pts, rng, 0.03, 0.03) for _ in range(4)]
        for key in err:
            with pytest.MonkeyPatch.context() as mp:
                if key == "off":
                    mp.setattr(fitter_module, off_patch, lambda *args: None)
                f = Fitter(FitConfig(body_height_m=1.6))
                rs = [f.fit(frames[i], i, 0.1 * i, SIZE, mode=mode, intrinsics=k, world=worlds[i])
                      for i in range(4)]
            assert all(r.ok for r in rs)
            err[key].append(np.mean([abs(r.variables[h] - pose.joints[h]) for r in rs[1:] for h in HINGES.values()]))
    return np.array(err["on"]), np.array(err["off"])


def test_image_mode_reads_the_knees_and_elbows_closer_with_the_world_flexion():
    on, off = _hinge_errors("image", np.random.default_rng(8), "flexion_rows")
    # measured: 7.0 -> 5.9 degrees, 11 of 15 scenes better
    assert on.mean() < off.mean() - 0.2 and (on < off).sum() >= 10, (off.mean(), on.mean(), (on < off).sum())


def test_video_mode_reads_the_knees_and_elbows_closer_with_the_world_flexion():
    on, off = _hinge_errors("video", np.random.default_rng(7), "flexion_prior")
    # measured: 5.9 -> 5.4 degrees, 13 of 15 scenes better
    assert on.mean() < off.mean() - 0.2 and (on < off).sum() >= 10, (off.mean(), on.mean(), (on < off).sum())
