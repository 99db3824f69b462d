"""The analytic starting points (fitting.analytic.analytic_start) against the same choice written as a plain
Python loop, and what they are for: limbs placed on their own 2D landmarks."""

import numpy as np

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import loss as LOSS
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.analytic import analytic_start
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.warmup import warmup_landmarks

DIMS = BodyDimensions.from_height(1.7)


def _frame(noise_px: float = 0.0, seed: int = 1) -> P.Frame:
    cfg = FitConfig()
    xy, w, _ = P.landmark_weights(warmup_landmarks(DIMS, noise_px, seed), cfg)
    return P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS))


def reference_start(seed: np.ndarray, data: np.ndarray) -> np.ndarray:
    """Each limb in turn, both depth signs, the smallest loss kept (the seed's limb on a tie)."""
    work = FK.empty_work()
    x = seed.copy()
    trial = np.empty(L.N_VAR)
    for limb in range(4):
        best_loss, best_x = LOSS.pose_loss(x, data, work), x
        for sign in (1.0, -1.0):
            refine.limb_from_observation(x, data, limb, sign, trial)
            c = LOSS.pose_loss(trial, data, work)
            if c < best_loss:
                best_loss, best_x = c, trial.copy()
        x = best_x
    return x


def _seeds(frame: P.Frame) -> np.ndarray:
    lo, hi = P.image_box(FitConfig())
    return P.orientation_seeds(frame, DIMS, lo, hi)


def test_kernel_matches_the_python_loop():
    for noise, rng_seed in ((0.0, 1), (3.0, 2), (8.0, 3)):
        frame = _frame(noise, rng_seed)
        seeds = _seeds(frame)
        assert len(seeds) >= 2
        rng = np.random.default_rng(rng_seed)
        for seed in [*seeds, *(s + rng.normal(0, 0.3, L.N_VAR) * (np.arange(L.N_VAR) > 0) for s in seeds)]:
            out = np.empty(L.N_VAR)
            analytic_start(seed, frame.data, FK.empty_work(), out)
            np.testing.assert_array_equal(out, reference_start(seed, frame.data))


def test_limbs_land_on_their_landmarks():
    """From a seed with the limbs hanging straight, every limb is moved to its own landmarks: the 2D error
    drops far below the seed's and the raised arms come out raised."""
    frame = _frame()
    work = FK.empty_work()
    for seed in _seeds(frame):
        out = np.empty(L.N_VAR)
        analytic_start(seed, frame.data, work, out)
        seed_mp = LOSS.pose_loss_terms(seed, frame.data, work)[1]
        out_mp = LOSS.pose_loss_terms(out, frame.data, work)[1]
        assert out_mp < 0.5 * seed_mp
        assert np.all(np.degrees(np.abs(out[[L.X_TSH_L, L.X_TSH_R]])) > 45.0)   # the warm-up pose's raised arms
        np.testing.assert_array_equal(seed[:7], out[:7])                        # size, body and torso kept
