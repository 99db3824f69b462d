"""The out-of-domain fit benchmark (bench.ood): its metrics, the mocap landmarks, the depth simulator and a
tiny end-to-end run. The numbers of the full run live in docs/bench/fit.md."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from posed.bench import depth_sim as D
from posed.bench import mocap_landmarks as M
from posed.bench import ood


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def test_pa_mpjpe_is_zero_for_a_similar_copy_and_not_for_a_mirror():
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(12, 3)) * 0.3
    pred = 1.7 * truth @ _rotation(rng).T + np.array([0.4, -1.0, 3.0])
    assert ood.pa_mpjpe(pred, truth) < 1e-12
    assert ood.mpjpe(truth, truth) == 0.0
    assert ood.mpjpe(truth + [0.0, 0.0, 0.01], truth) == pytest.approx(0.01)
    # a reflection is not a similarity: the mirror image keeps an error (no improper rotation allowed)
    mirror = truth * np.array([1.0, 1.0, -1.0])
    assert ood.pa_mpjpe(mirror, truth) > 0.01
    # the alignment minimizes the sum of squared distances: never above the translation-only alignment's
    noisy = truth + rng.normal(size=truth.shape) * 0.01
    aligned = ood.procrustes_align(noisy, truth)
    shifted = noisy - noisy.mean(0) + truth.mean(0)
    assert 0.0 < ((aligned - truth) ** 2).sum() <= ((shifted - truth) ** 2).sum()


def _standing() -> np.ndarray:
    j = {n: np.zeros(3) for n in M.BODY12}
    for s, x in (("left", 0.2), ("right", -0.2)):
        j[f"{s}_shoulder"] = np.array([x, -0.5, 0.0])
        j[f"{s}_elbow"] = np.array([x, -0.25, 0.0])
        j[f"{s}_wrist"] = np.array([x, -0.25, -0.25])     # forearm pointing at the camera (dz = -0.25)
        j[f"{s}_hip"] = np.array([x / 2, 0.0, 0.0])
        j[f"{s}_knee"] = np.array([x / 2, 0.4, 0.03])     # thigh nearly parallel to the image (dz 0.03)
        j[f"{s}_ankle"] = np.array([x / 2, 0.8, 0.2])     # shank going away (dz 0.17)
    return np.array([j[n] for n in M.BODY12])


def test_depth_flips_count_only_segments_with_a_clear_true_depth_difference():
    truth = _standing()
    i = {n: k for k, n in enumerate(M.BODY12)}
    assert ood.depth_flips(truth, truth) == (0, 4)      # forearms and shanks; upper arms (0) and thighs (3 cm) not
    pred = truth.copy()
    pred[i["left_wrist"], 2] = +0.25                      # left forearm mirrored in depth: a flip
    pred[i["right_knee"], 2] = -0.03                      # thigh's sign changes, but |true dz| < 5 cm: not counted
    assert ood.depth_flips(pred, truth) == (1, 4)
    pred[i["right_ankle"], 2] = -0.2                      # right shank now goes toward the camera: a flip
    assert ood.depth_flips(pred, truth) == (2, 4)


def test_flip_table_bins_the_fit_and_the_sensor_by_true_depth_difference():
    truth = _standing()
    i = {n: k for k, n in enumerate(M.BODY12)}
    measured = truth[:, 2] + 3.0                           # a depth camera 3 m away, exact
    table = ood.flip_table(truth, truth, measured)
    # forearms: |dz| 0.25 (last bin); shanks: 0.17 (0.12-0.2); thighs (3 cm) and upper arms not counted
    assert table.tolist() == [[0, 0, 0, 0], [0, 0, 0, 0], [2, 0, 0, 0], [2, 0, 0, 0]]
    pred = truth.copy()
    pred[i["left_wrist"], 2] = +0.25                       # the fit flips the left forearm
    measured[i["right_ankle"]] = measured[i["right_knee"]] - 0.01   # the sensor says the right shank comes closer
    measured[i["left_ankle"]] = np.nan                     # a hole
    table = ood.flip_table(pred, truth, measured)
    assert table.tolist() == [[0, 0, 0, 0], [0, 0, 0, 0], [2, 0, 1, 1], [2, 1, 0, 0]]
    assert table.sum(0)[:2].tolist() == list(ood.depth_flips(pred, truth))[::-1]


def test_segment_angles_from_positions():
    j = _standing()
    a = dict(zip(ood.ANGLE_NAMES, ood.segment_angles(j), strict=True))
    assert a["elbow_l"] == pytest.approx(90.0) and a["elbow_r"] == pytest.approx(90.0)   # forearm toward camera
    assert a["shoulder_l"] == pytest.approx(0.0, abs=1e-9)                               # arm along the trunk
    knee = math.degrees(math.atan2(0.17, 0.4) - math.atan2(0.03, 0.4))
    assert a["knee_l"] == pytest.approx(knee)
    # the same angles whatever the camera: rotation- and translation-invariant
    rot = _rotation(np.random.default_rng(3))
    assert np.allclose(ood.segment_angles(j @ rot.T + 1.0), ood.segment_angles(j))


def test_depth_simulator_statistics():
    """Noise RMS = sigma_k z^2 (sample sd within 4 standard errors, 1/sqrt(2N) relative), hole and background
    rates within 4 binomial standard deviations, everything else finite."""
    k = M.intrinsics()
    rng = np.random.default_rng(5)
    n_frames = 1000
    for z0 in (2.0, 4.0):
        pts = np.zeros((33, 3))
        pts[:, 2] = z0                                   # all on the optical axis: inside the image
        quiet = D.DepthSim(hole_rate=0.0, background_rate=0.0, self_occlusion=False)   # all points coincide
        d = np.array([D.simulate_depth(pts, k, rng, quiet) for _ in range(n_frames)])
        surface = z0 - D.SURFACE_OFFSET_M                # on the axis the ray is z itself
        resid = d - surface
        n = resid.size
        sd = float(np.sqrt(np.mean(resid ** 2)))
        want = D.SIGMA_K * float(np.sqrt(np.mean(surface ** 4)))
        assert abs(sd / want - 1.0) < 4.0 / math.sqrt(2 * n), (z0, sd, want)
        assert abs(float(resid.mean())) < 4.0 * want / math.sqrt(n)
    assert D.SIGMA_K * 9.0 == pytest.approx(0.030, abs=0.001)    # about 3 cm at 3 m, as stated
    sim = D.DepthSim(self_occlusion=False)
    pts = np.zeros((33, 3))
    pts[:, 2] = 3.0
    d = np.array([D.simulate_depth(pts, k, rng, sim) for _ in range(n_frames)])
    n = d.size
    holes = float(np.isnan(d).mean())
    back = float((d - 3.0 > 0.9).mean())
    for rate, p in ((holes, sim.hole_rate), (back, sim.background_rate)):
        assert abs(rate - p) < 4.0 * math.sqrt(p * (1 - p) / n)
    lo, hi = sim.background_behind_m
    far = d[d - 3.0 > 0.9]
    assert far.min() >= 3.0 + lo and far.max() <= 3.0 + hi
    # outside the image: unknown
    out = pts.copy()
    out[0] = [10.0, 0.0, 3.0]
    assert np.isnan(D.simulate_depth(out, k, rng, sim)[0])


def _person_33(z0: float) -> np.ndarray:
    """33 points of a person standing 3 m in front of the camera, facing it, arms hanging a little away from the
    body (camera frame: x right, y down, z forward; the person's left on the image's right)."""
    from posed.landmarks import LANDMARK_NAMES
    at = {"nose": (0.0, -0.68, -0.10), "left_ear": (0.07, -0.70, 0.0), "right_ear": (-0.07, -0.70, 0.0),
          "shoulder": (0.18, -0.50, 0.0), "elbow": (0.26, -0.22, 0.0), "wrist": (0.28, 0.03, 0.0),
          "hip": (0.08, 0.0, 0.0), "knee": (0.09, 0.45, 0.0), "ankle": (0.09, 0.88, 0.0)}
    pts = np.zeros((33, 3))
    for i, name in enumerate(LANDMARK_NAMES):
        side, _, part = name.partition("_")
        if name in at:
            pts[i] = at[name]
        elif part in at and side in ("left", "right"):
            x, y, z = at[part]
            pts[i] = (x if side == "left" else -x, y, z)
        else:                                   # other face, hand and foot points: near the nose, wrist, ankle
            near = "wrist" if part in ("pinky", "index", "thumb") else "ankle" if part in ("heel", "foot_index") \
                else "nose"
            x, y, z = at[near] if near == "nose" else at[near]
            pts[i] = (x if side != "right" else -x, y, z - 0.02)
    pts[:, 2] += z0
    return pts


def test_self_occlusion_hides_the_far_side_seen_from_the_side_and_nothing_from_the_front():
    """Facing the camera every body landmark shows its own surface; turned 90 degrees (the left side towards the
    camera) the far (right) shoulder and hip are behind the torso: the camera measures the torso's near
    surface, more than 20 cm in front of their own; the near side's shoulder, elbow, knee and ankle still show
    their own."""
    k = M.intrinsics()
    rng = np.random.default_rng(1)
    exact = D.DepthSim(sigma_k=0.0, hole_rate=0.0, background_rate=0.0)
    idx = {n: i for i, n in enumerate(__import__("landmarks").LANDMARK_NAMES)}
    body = [idx[f"{s}_{p}"] for s in ("left", "right")
            for p in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]

    def own(p):
        return p[:, 2] * (1.0 - D.SURFACE_OFFSET_M / np.linalg.norm(p, axis=1))

    front = _person_33(3.0)
    d = D.simulate_depth(front, k, rng, exact)
    assert np.allclose(d[body], own(front)[body], atol=1e-9)
    centre = np.array([0.0, 0.0, 3.0])
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])   # the person's left to the camera
    side = (front - centre) @ turn.T + centre
    assert side[idx["left_shoulder"], 2] < side[idx["right_shoulder"], 2]
    d = D.simulate_depth(side, k, rng, exact)
    for far in ("right_shoulder", "right_hip"):
        i = idx[far]
        assert own(side)[i] - d[i] > 0.20, far
        assert d[i] == pytest.approx(D.first_body_hit(side)[i])
    for near in ("left_shoulder", "left_elbow", "left_knee", "left_ankle"):   # (the hanging hand hides the hip)
        assert d[idx[near]] == pytest.approx(own(side)[idx[near]], abs=1e-9), near
    # without self-occlusion the far side shows its own surface
    d = D.simulate_depth(side, k, rng, D.DepthSim(sigma_k=0.0, hole_rate=0.0, background_rate=0.0,
                                                   self_occlusion=False))
    assert np.allclose(d[body], own(side)[body], atol=1e-9)


def test_mocap_landmarks_33x5_with_the_body_finite_and_in_view(shared_data):
    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    assert 1.45 < clip.height_m < 1.7
    t, pts = clip.resample(10.0)
    assert t[1] == pytest.approx(0.1) and pts.shape == (len(t), 33, 3)
    # the source runs at 120.0005 fps (frame time 0.0083333 s): 0.1 s is 4e-5 frames past frame 12, which
    # moves a point by at most 4e-5 x its per-frame motion (< 3 cm at 120 fps): within 1e-5 m
    assert np.allclose(pts[0], clip.points[0]) and np.allclose(pts[1], clip.points[12], atol=1e-5)
    t15, pts15 = clip.resample(15.0)
    assert np.allclose(pts15[1], clip.points[8], atol=1e-5)
    t7, pts7 = clip.resample(7.0)           # a time between two source frames is interpolated linearly
    u = t7[1] * clip.source_fps
    w = u - math.floor(u)
    assert 0.05 < w < 0.95
    assert np.allclose(pts7[1], (1 - w) * clip.points[int(u)] + w * clip.points[int(u) + 1])
    for az in (0.0, 135.0, 270.0):
        cam = M.choose_distance(clip, az)
        assert 2.5 <= cam.distance_m <= 5.0 and M.in_view(cam, pts)
        for p in cam.to_camera(pts)[::10]:
            lm = M.project(p, cam.intrinsics)
            assert lm.shape == (33, 5)
            assert np.isfinite(lm[M.BODY12_IDX]).all() and (lm[M.BODY12_IDX, 3] == 0.99).all()
            assert abs(lm[23, 2] + lm[24, 2]) < 1e-9       # z relative to the mid-hip
            truth = M.truth_joints(p)
            assert truth.shape == (12, 3) and np.allclose(0.5 * (truth[6] + truth[7]), 0.0)
    # the mocap's own hip joints, not the model's 0.115 H hip width
    hip_w = np.linalg.norm(clip.points[0, 23] - clip.points[0, 24])
    assert 0.12 < hip_w < 0.15 and abs(hip_w - 0.115 * clip.height_m) > 0.03


def test_correlated_noise_has_unit_variance_and_the_asked_correlation_time():
    """AR(1) per coordinate: standard deviation 1, lag correlation exp(-lag / (fps tau)) (within 4 standard
    errors over 20 000 frames x 66 coordinates, effectively fewer: the samples are correlated)."""
    rng = np.random.default_rng(8)
    fps, tau = 30.0, 0.5
    e = ood.correlated_noise(rng, 20000, fps, tau)
    assert e.shape == (20000, 33, 2)
    assert float(e.std()) == pytest.approx(1.0, abs=0.02)
    for lag in (1, 15, 30):
        r = float(np.mean(e[lag:] * e[:-lag]))
        assert r == pytest.approx(math.exp(-lag / (fps * tau)), abs=0.02), lag


def test_correlated_landmarks_share_truth_and_depth_with_independent_ones(shared_data):
    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    a = ood.build_sequence(clip, 45.0, 10, (0.01,), seed=3, max_s=2.0)
    b = ood.build_sequence(clip, 45.0, 10, (0.01,), seed=3, max_s=2.0, noise_corr_s=0.5)
    assert np.array_equal(a.truth, b.truth) and np.array_equal(a.depth, b.depth, equal_nan=True)
    clean = ood.build_sequence(clip, 45.0, 10, (0.0,), seed=3, max_s=2.0).landmarks[0]
    da, db = a.landmarks[0][:, :, :2] - clean[:, :, :2], b.landmarks[0][:, :, :2] - clean[:, :, :2]
    assert 0.5 < da.std() / db.std() < 2.0                      # the same noise level
    lag1 = [float(np.corrcoef(d[1:].ravel(), d[:-1].ravel())[0, 1]) for d in (da, db)]
    assert abs(lag1[0]) < 0.1 and lag1[1] > 0.6                  # 0.1 s apart: exp(-0.2) = 0.82


def test_tiny_end_to_end_run_has_every_metric(shared_data):
    from posed.bench import fit as bench
    from posed.bench.commands.fit import markdown
    from posed.fitting import FitConfig

    tiny = ood.OodPlan(clips=("131_01",), azimuths=(90.0,), fps=(15, 30), noises=(0.0, 0.01),
                       depth=(False, True), max_s=0.4)
    plan = bench.Plan(paper_yaws=(30.0,), floor_yaws=(), motion_yaws=(), seeds=(0,), motion_seeds=(0,),
                      settings=((6, 6),), noises=(0.0,), table3=False, sequences=(), ood=tiny)
    report = bench.run(plan, FitConfig(), protocols=["paper_poses", "ood_mocap"])
    json.dumps(report)
    rows = report["results"]
    assert {r["protocol"] for r in rows} == {"paper_poses", "ood_mocap"}
    assert all(r["domain"] == "in-domain" for r in rows if r["protocol"] == "paper_poses")
    out = [r for r in rows if r["protocol"] == "ood_mocap"]
    assert all(r["domain"] == "out-of-domain" for r in out)
    # 2 bodies x 2 modes, and video mode for a person seen before, x 2 fps x 3 noises (none, independent,
    # correlated in time) x 3 evidence settings (landmarks alone, with world landmarks, with depth)
    assert sorted((r["body"], r["mode"], r["fps"], r["noise_rel"], r["noise_corr_s"], r["depth"], r["world"])
                  for r in out) == sorted(
        (b, m, f, n, c, d, w) for b, m in (("height", "image"), ("height", "video"), ("mocap", "image"),
                                           ("mocap", "video"), ("seen", "video")) for f in (15, 30)
        for n, c in ((0.0, 0.0), (0.01, 0.0), (0.01, 0.5)) for d, w in ((False, False), (False, True), (True, False)))
    takes = ood.fitter_takes_depth()
    for r in out:
        assert r["frames"] == (13 if r["fps"] == 30 else 7) and r["failed"] == 0
        for key in ("pa_mpjpe_mm", "mpjpe_mm", "depth_flip_rate", "angle_err_deg", "ms_per_frame", "err2d_px"):
            assert r[key] is not None and r[key] >= 0, key
        assert r["pa_mpjpe_mm"] <= r["mpjpe_mm"] + 1e-6        # the similarity can only lower the error
        assert 0.0 <= r["depth_flip_rate"] <= 1.0 and r["depth_flip_segments"] > 0
        bins = r["depth_flips_by_true_dz"]
        assert sum(b["segments"] for b in bins) == r["depth_flip_segments"]
        assert sum(b["segments"] * (b["fit_flip_rate"] or 0) for b in bins) == pytest.approx(
            r["depth_flip_rate"] * r["depth_flip_segments"], abs=0.01)
        assert r["depth_used"] == (r["depth"] and takes)
        assert "root_cam_err_m" in r                           # null until the fitter reports root_cam_m
    # image mode: the 15 fps frames are the even 30 fps frames, fitted once, so identical numbers
    # the mocap's own proportions (an oracle calibration) fit the landmarks better than the height ratios
    e2d = {(r["body"], r["mode"], r["fps"], r["noise_rel"], r["depth"]): r["err2d_px"] for r in out
           if r["noise_corr_s"] == 0}
    assert e2d[("mocap", "image", 30, 0.0, False)] < e2d[("height", "image", 30, 0.0, False)]
    cams = report["protocol"]["ood_mocap"]["cameras"]
    assert len(cams) == 1 and 2.5 <= cams[0]["distance_m"] <= 5.0
    text = markdown(report)
    assert "Out-of-domain" in text and "In-domain" in text and "| height | image | 30 |" in text
    assert "| noise corr s |" in text
    with pytest.raises(ValueError, match="unknown protocol"):
        bench.run(plan, FitConfig(), protocols=["nope"])


def test_a_person_seen_before_starts_from_what_was_learned(shared_data):
    """The "seen" body: video mode over an earlier visit learns the subject's arms (the CMU subject's are 14-16 %
    shorter than the height ratios give); a minute later, well past ``proportions_forget_s``, the first frame of
    the clip is fitted with those arms (fitting.proportions retain), not with the configured ones."""
    from dataclasses import replace

    from posed.fitting import FitConfig, Fitter

    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    visit = ood.build_sequence(clip, 135.0, 10, (0.0,), seed=3, max_s=8.0)
    seq = ood.build_sequence(clip, 45.0, 10, (0.0,), seed=4, max_s=1.0)
    cfg = replace(FitConfig(), body_height_m=round(clip.height_m, 3), calibration="")
    fitter = Fitter(cfg)
    end = ood._visit(fitter, visit, 0, 1, False)
    assert end == pytest.approx(float(visit.times[-1]))
    learned = fitter._learner.scale.of("upper_arm_m")
    assert learned < 0.97                                          # the arms were learned shorter
    k = seq.camera.intrinsics
    t = end + cfg.proportions_forget_s + 30.0
    first = fitter.fit(seq.landmarks[0][0], 0, t, k.size, mode="video", intrinsics=k)
    assert first.ok and first.extra["limb_scale"]["upper_arm"] == round(learned, 3)
    fresh = Fitter(cfg).fit(seq.landmarks[0][0], 0, t, k.size, mode="video", intrinsics=k)
    assert fresh.extra["limb_scale"]["upper_arm"] == 1.0
