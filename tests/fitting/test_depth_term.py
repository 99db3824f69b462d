"""The robust depth term (fitting.depth_term) and the fit with depth: body surface in front of the joints,
holes, occluders, background hits; never worse than no depth when the depth is garbage."""

from __future__ import annotations

import numpy as np
import pytest

from posed.bench import mocap_landmarks as M
from posed.bench import simulate as S
from posed.fitting import BODY_LANDMARKS, BodyDimensions, FitConfig, Fitter
from posed.fitting.depth_term import (
    MIN_DEPTHS,
    SENSOR_DEPTH_CAMERA,
    SURFACE_M,
    SURFACE_SIGMA_M,
    depth_fit,
    occluder_front,
)

SIZE = (640, 480)
LIMBS = ((0, 2), (2, 4), (1, 3), (3, 5), (6, 8), (8, 10), (7, 9), (9, 11))  # body-landmark index pairs


def scene(name, yaw, distance=3.0, height=1.6):
    dims = BodyDimensions.from_height(height)
    camera = S.LevelCamera(model="pinhole", distance_m=distance, height_m=1.2)
    pose = S.pose(name, yaw)
    pts, _ = S._world_points(pose, dims, S.Placement(), camera.distance_m, camera.height_m)
    return dims, camera, pose, pts


def measured(pts, rng=None, sigma=0.0):
    """What the depth camera sees at the 33 landmarks: the surface in front of the 12 body joints (others
    unknown), with Gaussian noise ``sigma`` metres."""
    d = np.full(33, np.nan)
    d[list(BODY_LANDMARKS)] = pts[list(BODY_LANDMARKS), 2] - SURFACE_M
    if sigma > 0:
        d = d + rng.normal(0.0, sigma, 33)
    return d


def _near_solution(pose, dims, noise_px, seed, rng, jitter, intrinsics=None):
    """A solution near ``pose`` (its angles plus Gaussian ``jitter`` radians) of the problem that the rendering
    of ``pose`` with ``noise_px`` of landmark noise poses, perspective with ``intrinsics`` (else orthographic):
    (x, a copy of the problem's data, the model points in the camera frame, the landmarks' ray slopes
    ``(u - cx) / fx, (v - cy) / fy`` from their pixels, or None without intrinsics)."""
    from posed.fitting import forward_kinematics as FK
    from posed.fitting import layout as L
    from posed.fitting import problem as P
    from posed.fitting.result import MODEL_VARIABLE_NAMES

    lm = S.render(pose, dims=dims, noise_px=noise_px, seed=seed)
    xy, w, _ = P.landmark_weights(lm, FitConfig())
    assert (w > 0).all()
    data = P.pack(xy, w, dims, FitConfig(), P.reference_scale(xy, w, dims), intrinsics).data.copy()
    x = P.to_radians(np.array([1.0] + [pose.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))
    x[1:] += rng.normal(0.0, jitter, x.size - 1)
    pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
    FK.model_points(x, data, pts_b, pts_c)
    slopes = None if intrinsics is None else np.column_stack([(xy[:, 0] - intrinsics.cx) / intrinsics.fx,
                                                              (xy[:, 1] - intrinsics.cy) / intrinsics.fy])
    return x, data, pts_c, slopes


def test_consistent_depth_costs_nothing_and_gives_the_root():
    z_rel = np.linspace(-0.2, 0.2, 12)
    depth = 3.0 + z_rel - SURFACE_M
    d = depth_fit(z_rel, depth)
    assert d.cost == pytest.approx(0.0, abs=1e-12) and d.root_z == pytest.approx(3.0) and d.inliers == 12


def test_background_hits_occluders_and_holes_cost_at_most_one_each_and_do_not_move_the_root():
    z_rel = np.linspace(-0.2, 0.2, 12)
    depth = 3.0 + z_rel - SURFACE_M
    depth[0] += 3.0        # a silhouette edge: the wall behind
    depth[5] -= 0.5        # an arm or a table in front of the joint
    depth[[7, 9]] = np.nan  # holes
    d = depth_fit(z_rel, depth)
    assert d.root_z == pytest.approx(3.0, abs=1e-9)      # the 8 consistent votes decide
    assert 1.9 < d.cost < 2.0 and d.inliers == 8         # two outliers, each bounded by 1


def test_too_few_depths_is_no_term():
    depth = np.full(12, np.nan)
    depth[: MIN_DEPTHS - 1] = 3.0
    assert depth_fit(np.zeros(12), depth) is None


@pytest.mark.parametrize("seed", range(6))
def test_kernel_matches_numpy_reference(seed):
    """fitting.depth_rows.depth_term_kernel (numba, on a solution x) against depth_term.depth_fit (NumPy, on
    the same landmark depths): holes, background hits, occluders, and too few depths. Bound: the votes are
    sums of a few metres, so their median, inlier mean and costs agree to a few float64 ulps of 10 m."""
    from posed.fitting import layout as L
    from posed.fitting.depth_rows import depth_term_kernel

    rng = np.random.default_rng(seed)
    pose = S.pose(("walk_left_forward", "bend_grab", "sit_chair")[seed % 3], rng.uniform(-180, 180))
    k = M.intrinsics() if seed % 2 else None        # perspective: each landmark seen along its own ray
    x, data, pts_c, slopes = _near_solution(pose, BodyDimensions.from_height(1.6), 2.0, seed, rng, 0.2, k)
    z_rel = pts_c[:L.N_LM, 2]
    depth = rng.uniform(2.0, 5.0) + z_rel - SURFACE_M + rng.normal(0.0, 0.03, 12)
    depth[rng.random(12) < 0.15] = np.nan
    depth[rng.random(12) < 0.1] += rng.uniform(-1.0, 3.0)
    if seed == 5:
        depth[MIN_DEPTHS - 1:] = np.nan    # too few: no term
    targets, weights = np.empty(12), np.empty(12)
    n, cost, root, inliers, sigma = depth_term_kernel(x, data, depth, SENSOR_DEPTH_CAMERA, targets, weights)
    ref = depth_fit(z_rel, depth, occluder_front(pts_c[:L.N_LM], slopes))
    assert n == int((np.isfinite(depth) & (depth > 0)).sum())
    if ref is None:
        assert n < MIN_DEPTHS
        return
    tol = 16 * np.finfo(float).eps * 10.0
    assert root == pytest.approx(ref.root_z, abs=tol) and sigma == pytest.approx(ref.sigma, abs=tol)
    assert inliers == ref.inliers
    # costs: u = (vote - root) / sigma with sigma >= 3 cm, each term's slope in u at most ~0.65
    assert cost == pytest.approx(ref.cost, abs=12 * tol / SURFACE_SIGMA_M)
    np.testing.assert_allclose(targets, ref.targets, rtol=0, atol=tol)
    np.testing.assert_allclose(weights, ref.weights, rtol=0, atol=12 * tol / SURFACE_SIGMA_M)


def flips(result, pts):
    """Limb segments whose depth order (child nearer or farther than parent) differs from the truth, among
    those not nearly parallel to the image (true |dz| > 5 cm)."""
    fit = np.array([result.joints_3d[n] for n in list(result.joints_3d)[1:]])
    true = pts[list(BODY_LANDMARKS)]
    n = bad = 0
    for a, b in LIMBS:
        dz = true[b, 2] - true[a, 2]
        if abs(dz) > 0.05:
            n += 1
            bad += np.sign(fit[b, 2] - fit[a, 2]) != np.sign(dz)
    return bad, n


CASES = [(name, yaw) for name in ("stand_arms_front", "walk_left_forward", "bend_grab", "sit_chair", "kneel")
         for yaw in (-60.0, 20.0, 150.0)]


def test_depth_resolves_the_limbs_depth_order_and_garbage_depth_changes_nothing_for_the_worse():
    rng = np.random.default_rng(5)
    totals = {"none": [0, 0], "depth": [0, 0]}
    err = {"none": [], "garbage": []}
    for name, yaw in CASES:
        dims, camera, pose, pts = scene(name, yaw)
        lm = S.render(pose, dims=dims, camera=camera, image_size=SIZE, noise_px=2.0, seed=int(yaw) + 400)
        k = camera.intrinsics(SIZE)
        def fit(d, lm=lm, k=k):
            return Fitter(FitConfig(body_height_m=1.6)).fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=k, depth_m=d)

        plain, with_depth = fit(None), fit(measured(pts, rng, 0.03))
        garbage = fit(rng.uniform(0.5, 8.0, 33))
        for key, r in (("none", plain), ("depth", with_depth)):
            b, n = flips(r, pts)
            totals[key][0] += b
            totals[key][1] += n
        truth = pts[list(BODY_LANDMARKS)] - 0.5 * (pts[23] + pts[24])
        for key, r in (("none", plain), ("garbage", garbage)):
            fitted = np.array([r.joints_3d[n] for n in list(r.joints_3d)[1:]])
            err[key].append(np.linalg.norm(fitted - truth, axis=1).mean())
    # with a 3 cm-accurate depth camera far fewer limb segments are put on the wrong side in depth (measured:
    # 9 of 74 without depth, 2 with; the target of 2 % is measured out of domain in docs/bench/fit.md)
    assert totals["depth"][1] == totals["none"][1] > 20
    assert totals["none"][0] >= 5 and 3 * totals["depth"][0] <= totals["none"][0], totals
    # garbage depth: the robust term is flat, the fit is the one without depth (within 2 mm on average)
    assert abs(np.mean(err["garbage"]) - np.mean(err["none"])) < 0.002, (np.mean(err["garbage"]), np.mean(err["none"]))


def test_root_from_depth_holds_when_the_body_height_is_wrong():
    """Without depth a person taken 10 % taller is placed 10 % further away; depth places them right."""
    dims, camera, pose, pts = scene("stand_arms_front", 30.0)
    lm = S.render(pose, dims=dims, camera=camera, image_size=SIZE)
    k = camera.intrinsics(SIZE)
    truth = 0.5 * (pts[23] + pts[24])
    rng = np.random.default_rng(2)
    tall = Fitter(FitConfig(body_height_m=1.76))
    no_depth = tall.fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=k)
    assert no_depth.root_cam_m[2] - truth[2] > 0.2
    r = tall.fit(lm, 1, 0.1, SIZE, mode="image", intrinsics=k, depth_m=measured(pts, rng, 0.03))
    assert np.linalg.norm(np.array(r.root_cam_m) - truth) < 0.05, (r.root_cam_m, truth)
    assert r.extra["depth_inliers"] >= 10


def test_a_bad_depth_array_is_a_clear_failure():
    lm = S.render(S.pose("stand_arms_front", 30.0))
    r = Fitter().fit(lm, 0, 0.0, SIZE, depth_m=np.ones(12))
    assert not r.ok and "depth_m must be 33 values" in r.reason


def test_garbage_depth_is_judged_unusable_and_real_depth_usable():
    from posed.fitting.depth_term import usable

    z_rel = np.linspace(-0.2, 0.2, 12)
    good = 3.0 + z_rel - SURFACE_M
    good[[0, 1, 2]] += 3.0                     # three background hits still leave 9 of 12 in agreement
    assert usable(depth_fit(z_rel, good), good)
    garbage = np.random.default_rng(0).uniform(0.5, 8.0, 12)
    assert not usable(depth_fit(z_rel, garbage), garbage)


@pytest.mark.parametrize("seed", range(4))
def test_depth_rows_and_compared_cost_kernels_match_numpy(seed):
    """fitting.depth_rows.set_depth_rows_at and cost_with_depth against the same quantities from the NumPy
    depth term: rows w = sqrt(weight x robust weight) / sigma at the targets (NaN -> 0), off with too few
    depths or no weight; the compared cost is the sum of squares of every residual row but the depth rows,
    plus weight x the depth term's cost."""
    from posed.fitting import jacobian as JAC
    from posed.fitting import layout as L
    from posed.fitting.depth_rows import cost_with_depth, set_depth_rows_at

    rng = np.random.default_rng(100 + seed)
    pose = S.pose(("stand_arms_up", "bend_grab", "sit_chair", "fallen_sideways")[seed], rng.uniform(-180, 180))
    k = M.intrinsics() if seed % 2 else None
    x, data, pts_c, slopes = _near_solution(pose, BodyDimensions.from_height(1.7), 2.0, seed, rng, 0.1, k)
    data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = rng.uniform(0.5, 2.0, L.N_LM)   # stale rows of another start
    z_rel = pts_c[:L.N_LM, 2]
    depth = 3.0 + z_rel - SURFACE_M + rng.normal(0.0, 0.03, 12)
    depth[rng.random(12) < 0.2] = np.nan
    depth[seed] += 2.5                                           # a background hit
    ref = depth_fit(z_rel, depth, occluder_front(pts_c[:L.N_LM], slopes))
    weight = 0.7

    res = np.empty(L.N_RES)
    JAC.residuals_jacobian(x, data, res, np.empty((1, 1)), False)
    expected = float(np.sum(res[:L.R_DEPTH] ** 2)) + weight * ref.cost
    assert cost_with_depth(x, data, depth, SENSOR_DEPTH_CAMERA, weight) == pytest.approx(expected, rel=1e-12)
    assert cost_with_depth(x, data, np.full(12, np.nan), SENSOR_DEPTH_CAMERA, weight) == pytest.approx(expected - weight * ref.cost,
                                                                                 rel=1e-12)

    set_depth_rows_at(x, data, depth, SENSOR_DEPTH_CAMERA, weight)
    tol = 1e-12
    np.testing.assert_allclose(data[L.D_DEPTH:L.D_DEPTH + L.N_LM], np.where(np.isnan(ref.targets), 0.0, ref.targets),
                               rtol=0, atol=tol)
    np.testing.assert_allclose(data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM], np.sqrt(weight * ref.weights) / ref.sigma,
                               rtol=1e-9, atol=tol)
    assert data[L.D_DEPTH_W + seed] < 0.1 * np.sqrt(weight) / ref.sigma       # the background hit barely counts
    set_depth_rows_at(x, data, depth, SENSOR_DEPTH_CAMERA, 0.0)
    assert not data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM].any()
    data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = 1.0
    few = np.full(12, np.nan)
    few[:MIN_DEPTHS - 1] = 3.0
    set_depth_rows_at(x, data, few, SENSOR_DEPTH_CAMERA, weight)
    assert not data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM].any()


@pytest.mark.parametrize("azimuth", [45.0, 180.0])
def test_video_mode_with_depth_on_real_motion(shared_data, azimuth):
    """Video mode (the daemon's) on real motion capture with its own skeleton (CMU 131_01, the first 4 s at
    10 fps, 1 % landmark noise, a pinhole camera; bench.ood), fitted without depth, with the simulated D435's
    depth (surface offsets, holes, edge hits, z^2 noise) and with garbage depth: the real depth lowers the
    3D error and the depth flips of the limbs; garbage is judged unusable and changes nothing for the worse.
    At 180 degrees (walking away) the 2D landmarks alone leave the body's yaw ambiguous: depth settles it."""
    from posed.bench import mocap_landmarks as M
    from posed.bench import ood

    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    seq = ood.build_sequence(clip, azimuth, 10, (0.01,), seed=21, max_s=4.0)
    k = seq.camera.intrinsics
    rng = np.random.default_rng(3)
    scores = {}
    for name in ("none", "depth", "garbage"):
        fitter = Fitter(FitConfig(body_height_m=round(clip.height_m, 3)))
        pa, flipped, counted = [], 0, 0
        for i in range(len(seq.times)):
            depth = {"none": None, "depth": seq.depth[i], "garbage": rng.uniform(0.5, 8.0, 33)}[name]
            r = fitter.fit(seq.landmarks[0][i], i, float(seq.times[i]), k.size, mode="video", intrinsics=k,
                           depth_m=depth)
            assert r.ok, r.reason
            pred = ood.fitted_joints(r)
            pa.append(ood.pa_mpjpe(pred, seq.truth[i]))
            f, n = ood.depth_flips(pred, seq.truth[i])
            flipped, counted = flipped + f, counted + n
        scores[name] = (float(np.mean(pa)), flipped / counted)
    assert scores["depth"][0] < 0.85 * scores["none"][0], scores
    assert scores["depth"][1] < 0.7 * scores["none"][1], scores
    assert scores["garbage"][0] < scores["none"][0] + 0.003, scores     # metres: within 3 mm or better
    assert scores["garbage"][1] < scores["none"][1] + 0.02, scores


def _sim_depth(pts):
    """The benchmark's simulated depth camera without noise, holes or background: each landmark's own
    surface, or the body part in front of it (bench.depth_sim's capsules, not the fit's torso)."""
    from posed.bench import depth_sim as D

    return D.simulate_depth(pts, M.intrinsics(), np.random.default_rng(0),
                            D.DepthSim(sigma_k=0.0, hole_rate=0.0, background_rate=0.0))


def test_the_torso_hides_the_far_side_seen_from_the_side_and_the_term_expects_it():
    """Seen from the side the far shoulder and hip are behind the torso and the camera measures the torso's
    near surface there (the benchmark's independent body model). The true pose flags them hidden
    (occluder_front) and its votes agree; counted as if seen, they would cost nearly 1 each and pull the root.
    Facing the camera nothing is hidden."""
    def rays(p):   # each body landmark's line of sight from the pinhole camera
        b = p[list(BODY_LANDMARKS)]
        return b[:, :2] / b[:, 2:3]

    dims, camera, pose, pts = scene("stand_arms_front", 0.0)
    body = pts[list(BODY_LANDMARKS)]
    rel = body - 0.5 * (pts[23] + pts[24])
    assert np.isinf(occluder_front(rel, rays(pts))).all()
    for yaw in (90.0, -90.0):
        dims, camera, pose, pts = scene("stand_arms_front", yaw)
        rel = pts[list(BODY_LANDMARKS)] - 0.5 * (pts[23] + pts[24])
        far = [i for i in (0, 1, 6, 7) if rel[i, 2] > 0.05]          # the shoulder and hip away from the camera
        assert len(far) == 2
        depth = _sim_depth(pts)[list(BODY_LANDMARKS)]
        front = occluder_front(rel, rays(pts))
        assert np.isfinite(front[far]).all()
        aware, naive = depth_fit(rel[:, 2], depth, front), depth_fit(rel[:, 2], depth)
        true_root = 0.5 * (pts[23, 2] + pts[24, 2])
        assert abs(aware.root_z - true_root) < 0.02 and aware.inliers == 12
        assert naive.cost - aware.cost > 1.5, (naive.cost, aware.cost)
        assert np.isnan(aware.targets[far]).all() and (aware.weights[far] == 0).all()


@pytest.mark.parametrize("seed", range(3))
def test_occluder_front_kernel_matches_numpy(seed):
    """fitting.depth_rows.occluder_front_into (numba) against depth_term.occluder_front on model poses from every
    side (some landmarks hidden, most not), along the optical axis and along each landmark's pinhole ray (the
    kernel reads the slopes from the problem's observations and camera, the reference gets them from the
    pixels), a landmark of weight 0 along the ray through the landmarks' weighted centroid."""
    from posed.fitting import layout as L
    from posed.fitting.depth_rows import occluder_front_into

    rng = np.random.default_rng(50 + seed)
    dims = BodyDimensions.from_height(1.7)
    hidden = 0
    for k in range(24):
        pose = S.pose(("walk_left_forward", "bend_grab", "sit_chair", "stand_arms_front")[k % 4], 15.0 * k)
        _, data, pts_c, slopes = _near_solution(pose, dims, 1.0, k, rng, 0.1, M.intrinsics() if k % 3 else None)
        if slopes is not None and k % 2:   # a landmark without a usable pixel: the ray through the centroid
            w = data[L.D_W:L.D_W + L.N_LM].copy()
            j = k % L.N_LM
            data[L.D_W + j] = 0.0
            slopes[j] = w @ slopes / w.sum()
        got = np.empty(L.N_LM)
        occluder_front_into(pts_c, data, got)
        ref = occluder_front(pts_c[:L.N_LM], slopes)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
        hidden += int(np.isfinite(ref).sum())
    assert 0 < hidden < 24 * 12 // 4
