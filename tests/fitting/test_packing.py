"""The packing kernels (fitting.packing) behind fitting.problem.landmark_weights and reference_scale, against
the plain-Python functions they replaced, to the last bit, on visibilities, NaNs and postures of every kind;
and what they are for."""

import math

import numpy as np
import pytest

from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import BODY_LANDMARK_NAMES, BODY_LANDMARKS
from posed.fitting.warmup import warmup_landmarks

DIMS = BodyDimensions.from_height(1.7)
SEGMENTS = (((0, 1), 2 * DIMS.shoulder_half_m), ((6, 7), 2 * DIMS.hip_half_m), ((0, 2), DIMS.upper_arm_m),
            ((1, 3), DIMS.upper_arm_m), ((6, 8), DIMS.thigh_m), ((7, 9), DIMS.thigh_m), ((8, 10), DIMS.shank_m),
            ((9, 11), DIMS.shank_m))


def reference_weights(landmarks: np.ndarray, cfg: FitConfig):
    body = landmarks[list(BODY_LANDMARKS)]
    xy = body[:, :2].astype(np.float64)
    drop = cfg.visibility_drop
    span = max(cfg.visibility_full - drop, 1e-6)
    w, missing = [], []
    for i, (x, y, _, vis, _) in enumerate(body.tolist()):
        if math.isfinite(x) and math.isfinite(y) and math.isfinite(vis) and not vis < drop:
            w.append(min(max((vis - drop) / span, 0.05), 1.0))
        else:
            w.append(0.0)
            xy[i] = 0.0
            missing.append(BODY_LANDMARK_NAMES[i])
    return xy, np.array(w), missing


def reference_scale(xy: np.ndarray, w: np.ndarray) -> float:
    p, ok = xy.tolist(), (w > 0).tolist()
    ratios = [float(np.hypot(p[a][0] - p[b][0], p[a][1] - p[b][1])) / m for (a, b), m in SEGMENTS if ok[a] and ok[b]]
    if ok[0] and ok[1] and ok[6] and ok[7]:
        dx = 0.5 * (p[0][0] + p[1][0]) - 0.5 * (p[6][0] + p[7][0])
        dy = 0.5 * (p[0][1] + p[1][1]) - 0.5 * (p[6][1] + p[7][1])
        ratios.append(float(np.hypot(dx, dy)) / DIMS.trunk_m)
    best = 0.0
    for r in ratios:
        best = max(best, r)
    return best


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_kernels_match_the_python_functions_to_the_last_bit(seed):
    rng = np.random.default_rng(seed)
    cfg = FitConfig()
    for trial in range(500):
        lm = np.column_stack([rng.uniform(-50, 700, (33, 2)), rng.normal(0, 1, 33), rng.uniform(0, 1, 33),
                              rng.uniform(0, 1, 33)])
        bad = rng.uniform(size=33) < 0.1
        lm[bad, rng.integers(0, 5)] = rng.choice([np.nan, np.inf, -np.inf])
        if trial % 7 == 0:
            lm[:, 3] = 1.0   # all visible
        xy, w, missing = P.landmark_weights(lm, cfg)
        want_xy, want_w, want_missing = reference_weights(lm, cfg)
        np.testing.assert_array_equal(xy, want_xy)
        np.testing.assert_array_equal(w, want_w)
        assert missing == want_missing
        assert P.reference_scale(xy, w, DIMS) == reference_scale(xy, w)


def test_non_contiguous_and_integer_landmarks_read_alike():
    lm = warmup_landmarks(DIMS)
    wide = np.zeros((33, 10))
    wide[:, ::2] = lm
    ints = np.round(lm).astype(np.int32)
    for other, want in ((wide[:, ::2], lm), (ints, ints.astype(np.float64))):
        got = P.landmark_weights(other, FitConfig())
        ref = P.landmark_weights(want, FitConfig())
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])


def test_weights_and_scale_of_a_standing_person():
    """The warm-up person (0.6 image heights tall, all visible): every weight 1, nothing missing, and the
    scale is the pixels per metre it was rendered with (a segment in the image plane shows its length)."""
    lm = warmup_landmarks(DIMS)
    xy, w, missing = P.landmark_weights(lm, FitConfig())
    assert missing == [] and np.all(w == 1.0)
    assert P.reference_scale(xy, w, DIMS) == pytest.approx(0.6 * 480 / DIMS.body_height_m, rel=0.02)
    lm[list(BODY_LANDMARKS)[4], 3] = 0.1   # the left wrist barely visible
    xy, w, missing = P.landmark_weights(lm, FitConfig())
    assert missing == ["left_wrist"] and w[4] == 0.0 and np.all(xy[4] == 0.0)


def reference_pack(xy, w, scale_px):
    """NumPy 2's sums written out: the 12 weights by eight running sums combined pairwise, then the rest; the
    weighted coordinates in turn."""
    sw = ((w[0] + w[1]) + (w[2] + w[3])) + ((w[4] + w[5]) + (w[6] + w[7])) + 0.0
    for v in w[8:]:
        sw += v
    c = [0.0, 0.0]
    for i in range(12):
        for a in (0, 1):
            c[a] += w[i] * xy[i][a]
    c = [c[0] / sw, c[1] / sw]
    return c, [(xy[i][a] - c[a]) / scale_px for i in range(12) for a in (0, 1)]


def test_normalized_landmarks_match_the_reference_to_the_last_bit():
    rng = np.random.default_rng(11)
    cfg = FitConfig()
    for _ in range(2000):
        xy = rng.uniform(-100, 900, (12, 2))
        w = rng.uniform(0.05, 1.0, 12) * (rng.uniform(size=12) > 0.25)
        if not w.any():
            continue
        frame = P.pack(xy, w, DIMS, cfg, 300.0)
        c, obs = reference_pack(xy.tolist(), w.tolist(), 300.0 * DIMS.body_height_m)
        assert frame.centroid_px.tolist() == c
        assert frame.data[L.D_OBS:L.D_OBS + 24].tolist() == obs
        assert frame.data[L.D_W:L.D_W + 12].tolist() == w.tolist()


def test_no_weight_gives_no_centroid():
    frame = P.pack(np.ones((12, 2)), np.zeros(12), DIMS, FitConfig(), 300.0)
    assert np.all(np.isnan(frame.centroid_px))


@pytest.mark.parametrize("shape", [(33, 4), (12, 5), (33,), (0, 5)])
def test_landmarks_of_the_wrong_shape_are_refused(shape):
    with pytest.raises(ValueError, match=r"\(33, 5\)"):
        P.landmark_weights(np.zeros(shape), FitConfig())


def test_body_array_holds_the_lengths_in_the_kernels_order():
    """BodyDimensions.as_array (the frame's D_DIMS block) lists every field in declaration order, which is the
    kernels' DM_* order; a learned body (scaled fields) gives its own lengths, not a cached array."""
    from dataclasses import fields

    arr = DIMS.as_array()
    assert arr.dtype == np.float64 and arr.shape == (L.N_DIMS,)
    assert arr.tolist() == [getattr(DIMS, f.name) for f in fields(BodyDimensions)]
    assert (arr[L.DM_H], arr[L.DM_TRUNK], arr[L.DM_TH], arr[L.DM_FOOT]) == (
        DIMS.body_height_m, DIMS.trunk_m, DIMS.thigh_m, DIMS.foot_length_m)
    learned = BodyDimensions(*(v * 1.1 for v in arr.tolist()))
    assert learned.as_array().tolist() == [v * 1.1 for v in arr.tolist()]
