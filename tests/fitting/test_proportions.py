"""Learned proportions (fitting.proportions): video mode learns the person's limb lengths, trunk and hip width
from the frames, and leaves a body that already fits alone.

Real motion with another skeleton: the CMU mocap clip (its arms 14-16 % shorter than the height ratios give,
its anatomical hip centres 22 % narrower than the model's landmark hips, its thighs 8 % longer) seen by a
pinhole camera; the model's own rendering: nothing changes; a seated person facing the camera: the thighs
point at it and are not taken for short thighs."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from posed.bench import mocap_landmarks as M
from posed.bench import ood
from posed.bench import simulate as S
from posed.fitting import BodyDimensions, FitConfig, Fitter, write_calibration
from posed.fitting import proportions as PR
from posed.fitting.kinematics import BODY_LANDMARKS


@pytest.fixture(scope="module")
def walk(shared_data):
    """131_01 (walk, stop, crouch) at 10 fps from 45 degrees, noise-free: (sequence, clip, true dims)."""
    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    seq = ood.build_sequence(clip, 45.0, 10, (0.0,), seed=7)
    return seq, clip, ood.mocap_dimensions(clip)


def _video(fitter: Fitter, seq, n: int | None = None) -> list:
    k = seq.camera.intrinsics
    lms = seq.landmarks[0]
    return [fitter.fit(lms[i], i, float(seq.times[i]), k.size, mode="video", intrinsics=k)
            for i in range(len(lms) if n is None else n)]


def test_learns_the_mocap_subjects_proportions_and_fits_it_better(walk):
    seq, clip, true = walk
    cfg = FitConfig(body_height_m=round(clip.height_m, 3))
    learned = Fitter(cfg)
    fixed = Fitter(replace(cfg, learn_proportions=False))
    res_l, res_f = _video(learned, seq), _video(fixed, seq)
    assert all(r.ok for r in res_l + res_f)
    scale = learned._learner.scale
    base = learned.base_dims
    # the direction and most of the size of every mismatch larger than 10 %, from the frames alone
    for f in ("upper_arm_m", "forearm_m", "hip_half_m"):
        truth = getattr(true, f) / getattr(base, f)
        assert truth < 0.9
        assert scale.of(f) < 0.95 and abs(scale.of(f) - truth) < 0.1, (f, scale.of(f), truth)
    assert scale.of("thigh_m") > 1.03
    # the configured height is kept: legs and trunk add up to it
    d = learned.dims
    assert d.thigh_m + d.shank_m + d.trunk_m == pytest.approx(base.thigh_m + base.shank_m + base.trunk_m)
    assert "limb_scale" in res_l[-1].extra and "limb_scale" not in res_f[-1].extra
    pa_l = np.mean([ood.pa_mpjpe(ood.fitted_joints(r), seq.truth[i]) for i, r in enumerate(res_l)][40:])
    pa_f = np.mean([ood.pa_mpjpe(ood.fitted_joints(r), seq.truth[i]) for i, r in enumerate(res_f)][40:])
    assert pa_l < 0.92 * pa_f, (pa_l, pa_f)   # after the first 4 s (learning)


def test_with_depth_the_lengths_are_measured_closer_to_the_subjects(walk):
    """The same walk with the simulated depth camera (its noise, holes, background hits and the body's own
    occlusions): the fit learns the lengths from 3D samples (``depth_samples`` in every result's limb_scale
    once there are some), and they land nearer the subject's than those learned from the image alone."""
    seq, clip, true = walk
    k = seq.camera.intrinsics
    lms = seq.landmarks[0]
    cfg = FitConfig(body_height_m=round(clip.height_m, 3))
    with_depth, image_only = Fitter(cfg), Fitter(cfg)
    res = [with_depth.fit(lms[i], i, float(seq.times[i]), k.size, mode="video", intrinsics=k, depth_m=seq.depth[i])
           for i in range(len(lms))]
    _video(image_only, seq)
    assert all(r.ok for r in res)
    assert "depth_samples" in res[-1].extra["limb_scale"]
    assert "depth_samples" not in image_only._learner.scale.to_json()
    base = with_depth.base_dims

    def error(f: Fitter) -> float:   # mean |learned - true| over the learned length fields, as ratios
        return float(np.mean([abs(f._learner.scale.of(n) - getattr(true, n) / getattr(base, n))
                              for n in ("upper_arm_m", "forearm_m", "thigh_m", "shank_m", "trunk_m", "hip_half_m")]))

    assert error(with_depth) < error(image_only), (error(with_depth), error(image_only))
    assert error(with_depth) < 0.05


def test_the_models_own_rendering_learns_nothing():
    """A rendering of the model itself fits exactly: the estimate stays inside the dead zone, the lengths are
    the configured ones to the last bit and the fit stays exact."""
    seq = S.sequence("squat", psi_bd=30.0)
    fitter = Fitter(FitConfig(body_height_m=1.6))
    results = [fitter.fit(lm, i, t, (640, 480), mode="video")
               for i, (t, lm, _) in enumerate(S.render_sequence(seq, fps=10.0))]
    assert all(r.ok for r in results)
    assert fitter._learner.scale.ratio == {} and fitter._learner.scale.size == 1.0
    assert fitter._learner.scale.samples["trunk"] >= PR.MIN_SAMPLES
    assert fitter.dims == fitter.base_dims
    assert max(r.extra["err2d_px"] for r in results) < 1e-3


def test_a_seated_person_facing_the_camera_keeps_the_thigh_length():
    """Thighs pointing at the camera project short and vertical; their shanks do not: no sample."""
    dims = S.body_dimensions(1.6)
    sit = S.pose("sit_chair", psi_bd=0.0)
    lm = S.render(sit, dims=dims)
    k = np.full(12, 0.6 * 480 / 1.6 / (480 * 0.6))  # orthographic, normalized units: g / H with g = 1
    obs = (lm[list(BODY_LANDMARKS), :2] - lm[list(BODY_LANDMARKS), :2].mean(axis=0)) / (480 * 0.6)
    got = [name for name, _ in PR.samples(obs, np.ones(12), k, dims)]
    assert "leg" not in got and "trunk" in got
    stand = S.render(S.STANDING, dims=dims)
    obs = (stand[list(BODY_LANDMARKS), :2] - stand[list(BODY_LANDMARKS), :2].mean(axis=0)) / (480 * 0.6)
    got = dict(PR.samples(obs, np.ones(12), k, dims))
    assert got["leg"] == pytest.approx((1.0, 1.0), abs=0.02)
    assert got["trunk"][0] == pytest.approx(1.0, abs=0.02)
    assert got["hip"][0] == pytest.approx(1.0, abs=0.02)


def test_samples_measure_shorter_limbs_in_the_image_plane():
    """A standing body with arms 20 % shorter and hips 30 % narrower than the model's, facing the camera."""
    model = S.body_dimensions(1.6)
    person = replace(model, upper_arm_m=0.8 * model.upper_arm_m, forearm_m=0.8 * model.forearm_m,
                     hip_half_m=0.7 * model.hip_half_m)
    lm = S.render(S.STANDING, dims=person)
    scale = 480 * 0.6 / 1.6   # px per metre of the default orthographic camera
    obs = lm[list(BODY_LANDMARKS), :2] / (scale * 1.6)
    k = np.full(12, 1.0 / 1.6)
    got = {}
    for name, r in PR.samples(obs, np.ones(12), k, model):
        got.setdefault(name, []).append(r)
    assert np.array(got["arm"]) == pytest.approx(0.8, abs=0.03)
    assert got["hip"][0][0] == pytest.approx(0.7, abs=0.02)
    # a missing wrist: that arm gives no sample; a torso landmark missing: no sample at all
    w = np.ones(12)
    w[4] = 0.0
    assert sum(name == "arm" for name, _ in PR.samples(obs, w, k, model)) == 1
    w[6] = 0.0
    assert PR.samples(obs, w, k, model) == []


def test_learner_bounds_shrinkage_and_height():
    base = BodyDimensions.from_height(1.7)
    learner = PR.ProportionLearner(base)
    k = np.ones(12)
    obs = np.zeros((12, 2))
    for _ in range(PR.MIN_SAMPLES - 1):
        learner.add("arm", [0.5, 0.5])
    assert learner._estimate().ratio == {}             # too few samples
    learner.observe(obs, np.zeros(12), k, base)        # no usable landmark: nothing added, nothing learned
    assert learner.scale.samples == {} and learner.dims() == base
    learner.add("arm", [math.nan, 0.5])                # a non-finite sample is left out
    assert learner._win["arm"].added == PR.MIN_SAMPLES - 1
    for _ in range(200):
        learner.add("arm", [0.5, 0.5])
    learner._scale = learner._estimate()
    assert learner.scale.of("upper_arm_m") == PR.BOUNDS[0]   # never below the bound
    d = learner.dims()
    assert d.body_height_m == base.body_height_m and d.thigh_m == base.thigh_m   # the arms are not the height
    # the window keeps the newest HISTORY samples: the old ones leave it and its percentile with them
    for _ in range(PR.HISTORY):
        learner.add("arm", [1.2, 1.2])
    assert len(learner._win["arm"].ring) == PR.HISTORY and learner._win["arm"].rank(75.0) == [1.2, 1.2]
    learner.forget()
    assert learner.dims() == base


def test_retained_proportions_are_the_prior_of_new_samples():
    """After a while without anybody (``retain``) the learned body stays in use, and new samples move it from
    there as they would move the configured body: by n / (n + PRIOR_SAMPLES) of their departure (image
    samples) or by their scatter (3D samples); ``forget`` goes back to the configured body."""
    base = BodyDimensions.from_height(1.7)
    learner = PR.ProportionLearner(base)
    for _ in range(80):
        learner.add("arm", [0.8, 0.9])
    learner._scale = learner._estimate()
    learned, dims = dict(learner.scale.ratio), learner.dims()
    assert learned["upper_arm_m"] == pytest.approx(1.0 - 0.2 * 80 / 100) and "thigh_m" not in learned
    learner.retain()
    assert learner.dims() == dims and all(w.added == 0 for w in learner._win.values())
    learner._scale = learner._estimate()                      # no samples yet: the retained body
    assert learner.scale.ratio == learned and learner.dims() == dims
    n = PR.MIN_SAMPLES
    for _ in range(n):                                        # someone with the configured arms
        learner.add("arm", [1.0, 1.0])
    learner._scale = learner._estimate()
    for f, v in (("upper_arm_m", 1.0), ("forearm_m", 1.0)):
        want = learned[f] + (v - learned[f]) * n / (n + PR.PRIOR_SAMPLES)
        assert learner.scale.ratio[f] == pytest.approx(want) and want < 1.0 - PR.DEAD_ZONE
    for _ in range(PR.MIN_DEPTH_SAMPLES):
        learner._win3["arm"].add([1.0, 1.0])                  # 3D samples that agree exactly: believed at once
    learner._scale = learner._estimate()
    assert "upper_arm_m" not in learner.scale.ratio          # 1.0: inside the dead zone
    learner.forget()
    assert learner.dims() == base and learner._win["arm"].prior == [1.0, 1.0]


def test_window_percentile_against_numpy():
    """The sorted window against NumPy's partition of the same last HISTORY samples."""
    rng = np.random.default_rng(3)
    win = PR._Window(("upper_arm_m", "forearm_m"), 75.0)
    rows = rng.normal(1.0, 0.1, size=(PR.HISTORY + 257, 2))
    for i, row in enumerate(rows):
        win.add(row.tolist())
        last = rows[max(0, i + 1 - PR.HISTORY):i + 1]
        for pct in (50.0, 75.0):
            kth = int(pct / 100.0 * (len(last) - 1))
            assert win.rank(pct) == np.partition(last, kth, axis=0)[kth].tolist()


def test_image_mode_calibration_forgetting_and_reset(walk, tmp_path):
    seq, clip, true = walk
    cfg = FitConfig(body_height_m=round(clip.height_m, 3))
    f = Fitter(cfg)
    _video(f, seq, 60)
    learned = f._learner.dims()       # what the next video frame fits with
    assert learned != f.base_dims
    k = seq.camera.intrinsics
    lm = seq.landmarks[0][60]
    r = f.fit(lm, 60, float(seq.times[60]), k.size, mode="image", intrinsics=k)
    assert f.dims == f.base_dims and "limb_scale" not in r.extra    # image mode: the configured body
    assert f._learner.dims() == learned                               # ... and it teaches nothing
    f.reset()                                                         # a lost track keeps what was learned
    f.fit(lm, 61, float(seq.times[60]) + 0.1, k.size, mode="video", intrinsics=k)
    assert f.dims == learned
    # a long gap (longer than proportions_forget_s): the same person may come back, or someone else: what was
    # learned is kept as the prior the new samples start from
    f.fit(lm, 62, float(seq.times[60]) + 0.2 + cfg.proportions_forget_s + 1, k.size, mode="video", intrinsics=k)
    assert f.dims == learned
    assert max(w.added for w in f._learner._win.values()) <= 2 and f._learner._win["arm"].prior[0] < 0.97
    f.fit(lm, 0, 0.0, k.size, mode="video", intrinsics=k)              # time went back: another recording
    assert f.dims == f.base_dims
    # warm-up teaches nothing
    _video(f, seq, 60)
    before = f._learner.dims()
    f.warmup()
    assert f._learner.dims() == before
    f.forget_body()
    assert f._learner.dims() == f.base_dims
    # a calibration file is a measurement: nothing is learned over it
    path = tmp_path / "user.yaml"
    write_calibration(path, true, frames=1)
    fc = Fitter(replace(cfg, calibration=str(path)))
    res = _video(fc, seq, 30)
    assert fc.dims == fc.base_dims and "limb_scale" not in res[-1].extra
    assert fc.dims.as_array() == pytest.approx(true.as_array(), abs=1e-4)   # the file's 4 decimals


@pytest.mark.parametrize("intrinsics", [False, True])
def test_image_scale_is_the_projections_derivative(intrinsics):
    """image_scale against a finite difference of the projection itself: a landmark moved by 1 mm parallel
    to the image plane moves by image_scale x 1 mm in the image (normalized units)."""
    from posed.camera_model import Intrinsics
    from posed.fitting import forward_kinematics as FK
    from posed.fitting import layout as L
    from posed.fitting import problem as P
    from posed.fitting.projection import image_scale, project

    dims = S.body_dimensions(1.6)
    cfg = FitConfig(body_height_m=1.6)
    lm = S.render(S.pose("walk_left_forward", 40.0), dims=dims)
    xy, w, _ = P.landmark_weights(lm, cfg)
    k = Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480) if intrinsics else None
    frame = P.pack(xy, w, dims, cfg, P.reference_scale(xy, w, dims), k)
    x = np.zeros(L.N_VAR)
    x[0] = 0.9
    x[L.X_PBD] = np.radians(35.0)
    x[L.X_TKN_L] = np.radians(40.0)
    pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
    FK.model_points(x, frame.data, pts_b, pts_c)
    base, moved = np.empty((L.N_LM, 3)), np.empty((L.N_LM, 3))
    project(x, pts_c, frame.data, base)
    shifted = pts_c.copy()
    shifted[:, 0] += 1e-3
    project(x, shifted, frame.data, moved)
    want = (moved[:, 0] - base[:, 0]) / 1e-3
    got = image_scale(x, frame.data)
    np.testing.assert_allclose(got, want, rtol=1e-9 if not intrinsics else 1e-6)
    assert intrinsics == (np.ptp(got) > 0)   # a pinhole's scale differs with each landmark's depth


def _shorter_armed(base: BodyDimensions) -> BodyDimensions:
    """A person with arms 15 % shorter, thighs 8 % longer and hips 20 % narrower than ``base``."""
    return replace(base, upper_arm_m=0.85 * base.upper_arm_m, forearm_m=0.85 * base.forearm_m,
                   thigh_m=1.08 * base.thigh_m, hip_half_m=0.8 * base.hip_half_m)


def _joints_anywhere(rng: np.random.Generator, person: BodyDimensions, depth_sd_m: float) -> np.ndarray:
    """The 12 body joints (camera frame, 3 m away) of ``person`` with arms and legs pointing in random
    directions, each joint's depth with ``depth_sd_m`` of noise."""

    def limb(start, lengths):
        out, p = [], np.asarray(start, float)
        for length in lengths:
            d = rng.normal(0.0, 1.0, 3)
            p = p + length * d / np.linalg.norm(d)
            out.append(p)
        return out

    sh = [np.array([s * person.shoulder_half_m, -person.trunk_m, 3.0]) for s in (1, -1)]
    hp = [np.array([s * person.hip_half_m, 0.0, 3.0]) for s in (1, -1)]
    arms = [limb(sh[i], (person.upper_arm_m, person.forearm_m)) for i in (0, 1)]
    legs = [limb(hp[i], (person.thigh_m, person.shank_m)) for i in (0, 1)]
    pts = np.array([sh[0], sh[1], arms[0][0], arms[1][0], arms[0][1], arms[1][1],
                    hp[0], hp[1], legs[0][0], legs[1][0], legs[0][1], legs[1][1]])
    pts[:, 2] += rng.normal(0.0, depth_sd_m, 12)
    return pts


def test_depth_measures_the_lengths_whatever_the_pose():
    """3D samples (joints placed from measured depth): a person with arms 15 % shorter, thighs 8 % longer and
    hips 20 % narrower than the model, arms and legs pointing anywhere (no image sample would count: nothing
    hangs in the image plane), each joint with 3 cm of depth noise, a few joints unknown (NaN) and one
    background hit per frame: the median of the noise-corrected lengths learns each within 2 %; the image
    samples are not needed."""
    base = BodyDimensions.from_height(1.7)
    person = _shorter_armed(base)
    rng = np.random.default_rng(4)
    learner = PR.ProportionLearner(base)
    for _ in range(200):
        pts = _joints_anywhere(rng, person, 0.03)
        pts[rng.integers(12)] = np.nan                 # a joint without a usable depth
        pts[rng.integers(12), 2] += 2.0                # the wall behind
        learner.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, pts, 0.03)
    scale = learner.scale
    assert not any(scale.samples.values()) and min(scale.depth_samples.values()) >= PR.MIN_DEPTH_SAMPLES
    # the learned lengths before the height normalization: ratio x size; each within 2 % of the person's
    for f in ("upper_arm_m", "forearm_m", "thigh_m", "hip_half_m"):
        want = getattr(person, f) / getattr(base, f)
        assert scale.ratio[f] == pytest.approx(want, rel=0.02), f
    assert "shank_m" not in scale.ratio and "trunk_m" not in scale.ratio   # unchanged: within the dead zone
    assert scale.to_json()["depth_samples"] == scale.depth_samples
    # without depth nothing of this is learned
    plain = PR.ProportionLearner(base)
    plain.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, None)
    assert plain.scale.ratio == {} and "depth_samples" not in plain.scale.to_json()


def test_3d_samples_that_agree_are_believed_after_a_few():
    """The 3D samples measure the lengths whatever the pose: MIN_DEPTH_SAMPLES samples that agree (1 cm of
    depth noise) learn the arms within 3 % (a fixed 20 pseudo-samples would leave them at 0.97); fewer learn
    nothing; samples that scatter are shrunk towards the configured body, less with each sample."""
    base = BodyDimensions.from_height(1.7)
    person = _shorter_armed(base)
    rng = np.random.default_rng(8)
    learner = PR.ProportionLearner(base)
    got = 0
    while got < PR.MIN_DEPTH_SAMPLES:                  # two arm samples per frame (left and right)
        assert "upper_arm_m" not in learner.scale.ratio
        learner.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, _joints_anywhere(rng, person, 0.01),
                        0.01)
        got = learner.scale.depth_samples["arm"]
    assert got <= PR.MIN_DEPTH_SAMPLES + 1
    for f in ("upper_arm_m", "forearm_m"):
        assert learner.scale.ratio[f] == pytest.approx(0.85, abs=0.03), f
    assert PR.percentile_variance(50.0) == pytest.approx(math.pi / 2)
    assert PR.percentile_variance(75.0) == pytest.approx(1.8568, abs=1e-4)       # 0.1875 / phi(0.6745)^2
    assert PR.shrink(0.85, 5, 0.0, math.pi / 2) == 0.85                          # no scatter: the samples
    assert PR.shrink(0.85, 10, PR.PRIOR_SD, 1.0) == pytest.approx(1.0 - 0.15 * 10 / 11)   # one pseudo-sample
    pulled = [PR.shrink(0.85, n, 0.2, math.pi / 2) for n in (5, 20, 80, 320)]
    assert all(0.85 < a < b < 1.0 for b, a in zip(pulled, pulled[1:], strict=False))
    assert PR.shrink(0.5, 1000, 0.0, 1.0) == PR.BOUNDS[0]
    # a window's estimate is shrink() of its median and interquartile scatter
    win = PR._Window(("upper_arm_m",), 50.0, scatter_prior=True)
    rows = rng.normal(0.85, 0.1, PR.MIN_DEPTH_SAMPLES + 6)
    for v in rows:
        win.add([float(v)])
    q1, med, q3 = np.sort(rows)[[int(0.25 * (len(rows) - 1)), int(0.5 * (len(rows) - 1)), int(0.75 * (len(rows) - 1))]]
    want = PR.shrink(float(med), len(rows), float(q3 - q1) / 1.3489795, math.pi / 2)
    assert win.learned()["upper_arm_m"] == pytest.approx(want, rel=1e-6) and want > med


def test_joint_points_back_projects_pixels_at_the_measured_depth_behind_the_surface():
    from posed.camera_model import Intrinsics

    k = Intrinsics(width=640, height=480, fx=600.0, fy=610.0, cx=320.0, cy=240.0)
    joints = np.column_stack([np.linspace(-0.4, 0.4, 12), np.linspace(-0.8, 0.8, 12), np.linspace(2.5, 3.5, 12)])
    surface = np.full(12, 0.05)
    px = np.column_stack([k.fx * joints[:, 0] / joints[:, 2] + k.cx, k.fy * joints[:, 1] / joints[:, 2] + k.cy])
    use = np.ones(12, dtype=bool)
    use[3] = False
    got = PR.joint_points(px, joints[:, 2] - surface, use, surface, k)
    assert np.allclose(got[use], joints[use], atol=1e-12) and np.isnan(got[3]).all()


def test_world_landmarks_measure_the_proportions_in_their_own_metres():
    """BlazePose's world landmarks as 3D samples: the person of ``_shorter_armed`` in metres that assume
    another body (all 8 % short) with a few per cent of error on each frame and a joint unknown now and
    then: the learned limb *proportions* are the person's within 2 % and the configured height is kept (their
    scale is not taken); ``world_samples`` counts them; no image or depth sample is needed."""
    base = BodyDimensions.from_height(1.7)
    person = _shorter_armed(base)
    rng = np.random.default_rng(11)
    learner = PR.ProportionLearner(base)
    for _ in range(40):
        world = 0.92 * _joints_anywhere(rng, person, 0.0) * rng.normal(1.0, 0.02)
        world -= 0.5 * (world[6] + world[7])                     # hip-centred, as BlazePose's
        world[rng.integers(12)] = np.nan                          # a landmark below the visibility cut
        learner.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, None, 0.0, world)
    scale = learner.scale
    assert not any(scale.samples.values()) and not scale.depth_samples
    assert min(scale.world_samples.values()) >= PR.MIN_DEPTH_SAMPLES
    assert scale.to_json()["world_samples"] == scale.world_samples
    d = learner.dims()
    assert d.thigh_m + d.shank_m + d.trunk_m == pytest.approx(base.thigh_m + base.shank_m + base.trunk_m)
    for f in ("upper_arm_m", "forearm_m", "thigh_m", "shank_m"):       # proportions: relative to the trunk
        want = getattr(person, f) / person.trunk_m
        assert getattr(d, f) / d.trunk_m == pytest.approx(want, rel=0.02), f
    assert set(scale.world_samples) == set(PR.WORLD_GROUPS) == {"arm", "leg", "trunk"}
    assert "hip_half_m" not in scale.ratio               # not the hips: the image measures them, without scale


def test_a_depth_camera_wins_over_the_world_landmarks():
    """Both streams on every frame, the world landmarks of a body with the configured arms and the depth camera
    measuring the person's 15 % shorter ones: the depth camera's lengths are the ones learned; without it the
    world landmarks' are."""
    base = BodyDimensions.from_height(1.7)
    person = _shorter_armed(base)
    rng = np.random.default_rng(12)
    both, world_only = PR.ProportionLearner(base), PR.ProportionLearner(base)
    for _ in range(20):
        depth_pts, world = _joints_anywhere(rng, person, 0.01), _joints_anywhere(rng, base, 0.0)
        both.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, depth_pts, 0.01, world)
        world_only.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, None, 0.0, world)
    assert both.scale.ratio["upper_arm_m"] == pytest.approx(0.85, abs=0.03)
    assert both.scale.depth_samples and both.scale.world_samples
    assert "upper_arm_m" not in world_only.scale.ratio               # the configured arms: the dead zone


def test_video_mode_learns_the_mocap_subjects_arms_from_world_landmarks_at_once(walk):
    """The CMU walk with world landmarks (its true joints, hip-centred; the fit gets them as BlazePose's):
    within the first second video mode has the subject's short arms (14-16 % shorter than the model's), which
    the image alone learns only from hanging arms after several seconds; every result says
    ``world_samples``; image mode learns nothing."""
    seq, clip, true = walk
    k = seq.camera.intrinsics
    lms = seq.landmarks[0]
    world = np.full((len(lms), 33, 5), np.nan)
    world[:, M.BODY12_IDX, :3] = seq.truth - 0.5 * (seq.truth[:, 6:7] + seq.truth[:, 7:8])
    world[:, M.BODY12_IDX, 3:] = 1.0
    cfg = FitConfig(body_height_m=round(clip.height_m, 3))
    with_world, image_only = Fitter(cfg), Fitter(cfg)
    n = 10                                                            # 1 s at 10 fps
    res = [with_world.fit(lms[i], i, float(seq.times[i]), k.size, mode="video", intrinsics=k, world=world[i])
           for i in range(n)]
    _video(image_only, seq, n)
    assert all(r.ok for r in res)
    assert "world_samples" in res[-1].extra["limb_scale"] and "world" in res[-1].extra["evidence"]
    base = with_world.base_dims
    for f in ("upper_arm_m", "forearm_m"):
        truth = getattr(true, f) / getattr(base, f)
        assert with_world._learner.scale.of(f) == pytest.approx(truth, abs=0.05), f
        assert image_only._learner.scale.of(f) > truth + 0.05, f         # the image: not yet (shrunk, few)
    still = Fitter(cfg)
    r = still.fit(lms[0], 0, 0.0, k.size, mode="image", intrinsics=k, world=world[0])
    assert r.ok and "limb_scale" not in r.extra and still.dims == still.base_dims


def test_image_samples_refine_the_world_landmarks_lengths_unless_the_person_was_seen_before():
    """Once a group has MIN_SAMPLES image samples, its estimate is the image's, shrunk towards the world
    landmarks' lengths (PRIOR_SAMPLES pseudo-samples) instead of towards the configured body; after ``retain``
    (the person seen before) the image's estimate is shrunk towards what was learned of them, as without world
    landmarks."""
    base = BodyDimensions.from_height(1.7)
    person = _shorter_armed(base)
    rng = np.random.default_rng(13)
    learner = PR.ProportionLearner(base)

    def frame() -> None:
        learner.observe(np.zeros((12, 2)), np.zeros(12), np.ones(12), base, None, 0.0,
                        _joints_anywhere(rng, person, 0.0))

    for _ in range(5):
        frame()
    world_arm = learner.scale.ratio["upper_arm_m"]
    assert world_arm == pytest.approx(0.85, abs=0.01)               # the world landmarks alone so far
    for _ in range(PR.MIN_SAMPLES):
        learner.add("arm", [0.95, 0.95])
    frame()
    n = PR.MIN_SAMPLES
    want = PR.toward_prior(0.95, n, PR.PRIOR_SAMPLES, learner._winw["arm"].learned()["upper_arm_m"])
    assert learner.scale.ratio["upper_arm_m"] == pytest.approx(want, rel=1e-9)
    assert 0.85 < want < 0.95
    learned = learner.scale.ratio["upper_arm_m"]
    learner.retain()
    for _ in range(PR.MIN_SAMPLES):
        learner.add("arm", [1.0, 1.0])
    frame()
    assert learner.scale.ratio["upper_arm_m"] == pytest.approx(
        PR.toward_prior(1.0, PR.MIN_SAMPLES, PR.PRIOR_SAMPLES, learned), rel=1e-9)
