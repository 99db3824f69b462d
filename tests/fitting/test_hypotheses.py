"""The hypotheses kernel (fitting.hypotheses.best_hypothesis) against the Python loop it replaced, to the last
bit, with and without measured depth, and what it is for: the start nearest the truth wins."""

import math

import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.analytic import analytic_start
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.depth_rows import cost_with_depth, set_depth_rows_at
from posed.fitting.depth_term import SENSOR_DEPTH_CAMERA
from posed.fitting.hypotheses import best_hypothesis, video_starts
from posed.fitting.kinematics import BODY_LANDMARKS
from posed.fitting.warmup import warmup_depth, warmup_landmarks

DIMS = BodyDimensions.from_height(1.7)
LO, HI = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD
NO_DEPTH = np.full(L.N_LM, np.nan)


def _problem(noise_px: float, seed: int, perspective: bool = True) -> tuple[P.Frame, np.ndarray]:
    """A frame of the warm-up person (rendered orthographically; fitted with a pinhole camera when
    ``perspective``) and its hypotheses: the analytic starts, their limb mirrors and perturbed copies of the
    first three."""
    cfg = FitConfig()
    xy, w, _ = P.landmark_weights(warmup_landmarks(DIMS, noise_px, seed), cfg)
    k = Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480) if perspective else None
    frame = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS), k)
    starts = []
    for s in P.orientation_seeds(frame, DIMS, *P.image_box(cfg)):
        x = np.empty(L.N_VAR)
        analytic_start(s, frame.data, FK.empty_work(), x)
        starts.append(x)
        for limb in range(4):
            m = np.empty(L.N_VAR)
            refine.limb_flip(x, frame.data, limb, m)
            starts.append(m)
    rng = np.random.default_rng(seed)
    starts += [x + rng.normal(0.0, 0.1, L.N_VAR) * (np.arange(L.N_VAR) > 0) for x in starts[:3]]
    return frame, np.array(starts)


def reference_best(starts, data, depth, w_depth, trial_its, its, finalists):
    """The Python loop: every start refined ``trial_its``, sorted (stable), the best ``finalists`` refined
    again, the first smallest cost wins."""
    def refined(x0, n):
        out = np.empty(L.N_VAR)
        if depth is not None:
            set_depth_rows_at(x0, data, depth, SENSOR_DEPTH_CAMERA, w_depth)
        cost = refine.levenberg_marquardt(x0, LO, HI, data, n, out)[0]
        return out, (cost_with_depth(out, data, depth, SENSOR_DEPTH_CAMERA, w_depth) if depth is not None else float(cost))
    trials = sorted((refined(x, trial_its) for x in starts), key=lambda r: r[1])
    return min((refined(x, its) for x, _ in trials[:finalists]), key=lambda r: r[1])


@pytest.mark.parametrize("noise_px, seed", [(0.0, 1), (3.0, 2), (8.0, 3)])
@pytest.mark.parametrize("with_depth", [False, True])
def test_kernel_matches_the_python_loop(noise_px, seed, with_depth):
    frame, starts = _problem(noise_px, seed)
    prior = P.with_prior(frame, 0.01, starts[0], np.full(L.N_VAR, math.radians(10.0)), -1.0)
    depth = warmup_depth(DIMS)[list(BODY_LANDMARKS)] if with_depth else None
    if depth is not None:
        depth = depth + np.random.default_rng(seed).normal(0.0, 0.03, L.N_LM)
        depth[3] = np.nan   # a hole
        depth[5] += 2.0     # a background hit
    for data in (frame.data, prior):
        for trial_its, finalists in ((5, 2), (3, 1), (30, 4), (2, 50)):
            want_x, want_c = reference_best(starts, data.copy(), depth, 0.05, trial_its, 30, finalists)
            out = np.empty(L.N_VAR)
            got_c = best_hypothesis(starts, LO, HI, data.copy(), NO_DEPTH if depth is None else depth, SENSOR_DEPTH_CAMERA,
                                    depth is not None, 0.05, trial_its, 30, finalists, out)
            np.testing.assert_array_equal(out, want_x)
            assert got_c == want_c


def test_the_hypothesis_the_landmarks_support_wins():
    """Noise-free landmarks of the warm-up person, fitted with the projection they were rendered with: whatever
    the order of the starts, the winner fits them exactly and is the same solution."""
    frame, starts = _problem(0.0, 1, perspective=False)
    wins = []
    for order in (np.arange(len(starts)), np.arange(len(starts))[::-1]):
        out = np.empty(L.N_VAR)
        best_hypothesis(starts[order], LO, HI, frame.data.copy(), NO_DEPTH, SENSOR_DEPTH_CAMERA, False, 0.0, 5, 30, 2, out)
        wins.append(out)
    worst = max(refine.data_mse(x, frame.data) for x in starts)
    for x in wins:
        assert refine.data_mse(x, frame.data) < 1e-10 < worst
    np.testing.assert_allclose(wins[0], wins[1], atol=1e-4)


@pytest.mark.parametrize("mirrors", [0, 2, 4])
def test_video_starts_match_the_python_loop(mirrors):
    frame, starts = _problem(3.0, 2)
    seeds = P.orientation_seeds(frame, DIMS, *P.image_box(FitConfig()))
    for start in starts[:4]:
        want = [start.copy()]
        for limb in range(mirrors):
            m = np.empty(L.N_VAR)
            refine.limb_flip(start, frame.data, limb, m)
            want.append(m)
        for seed in seeds:
            a = np.empty(L.N_VAR)
            analytic_start(seed, frame.data, FK.empty_work(), a)
            want.append(a)
        out = np.full((len(want) + 1, L.N_VAR), 7.0)   # one row more: left as it was
        video_starts(start, seeds, mirrors, frame.data, FK.empty_work(), out)
        np.testing.assert_array_equal(out[:-1], np.array(want))
        assert np.all(out[-1] == 7.0)


def test_no_hypotheses_is_no_solution():
    frame, _ = _problem(0.0, 1)
    out = np.zeros(L.N_VAR)
    assert best_hypothesis(np.zeros((0, L.N_VAR)), LO, HI, frame.data.copy(), NO_DEPTH, SENSOR_DEPTH_CAMERA, False, 0.0, 5, 30, 2,
                           out) == np.inf
    assert np.all(np.isnan(out))
