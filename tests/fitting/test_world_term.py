"""BlazePose's world landmarks in the fit (fitting.world_term): their scale and depths as the depth term's
measurements, the fit choosing each limb's depth order with them, and a wrong world (the tracker on another
pose) not dragging the fit; off by config, never the source of ``root_cam_m``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.fitting import BODY_LANDMARKS, FitConfig, Fitter
from posed.fitting.world_term import WORLD_SIGMA_M, WORLD_Z0_M, world_depths, world_scale
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
