"""The pelvis-tilt projection (fitting.refine.pelvis_projection): the same choice as the unpruned search it
skips points of (every grid point and breakpoint evaluated), and what it is for: it moves along the null
direction only (no landmark moves) to the minimum of the pelvis-tilt prior."""

import math

import numpy as np
import pytest

from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.warmup import warmup_landmarks

DIMS = BodyDimensions.from_height(1.7)
LO, HI = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD


def unpruned(x, data):
    """The search without the bound: every 1-degree grid point, every breakpoint, then the golden-section
    polish (the kernel's steps, each point evaluated)."""
    from posed.fitting import forward_kinematics as FK
    upright = FK.torso_uprightness(x)
    f = lambda d: refine._prior_along(x, d, data, LO, HI, upright)   # noqa: E731
    best_d, best = 0.0, f(0.0)
    step, d = math.pi / 180.0, -math.pi
    while d <= math.pi:
        c = f(d)
        if c < best - 1e-12:
            best, best_d = c, d
        d += step
    for cand in (x[L.X_TTR], -x[L.X_THP_L], -x[L.X_THP_R], -x[L.X_TBD]):
        c = f(cand)
        if c < best - 1e-12:
            best, best_d = c, cand
    a, b, gr = best_d - step, best_d + step, 0.6180339887498949
    for _ in range(30):
        c1, c2 = b - gr * (b - a), a + gr * (b - a)
        if f(c1) < f(c2):
            b = c2
        else:
            a = c1
    mid = 0.5 * (a + b)
    return mid if f(mid) < best - 1e-12 else best_d


def _data(cfg: FitConfig) -> np.ndarray:
    xy, w, _ = P.landmark_weights(warmup_landmarks(DIMS), cfg)
    return P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS)).data


@pytest.mark.parametrize("cfg", [FitConfig(), FitConfig(prior_pelvis_upright=0.0), FitConfig(prior_lumbar=0.0),
                                 FitConfig(w_sag_tr=0.0)])
def test_same_choice_as_the_unpruned_search(cfg):
    data = _data(cfg)
    rng = np.random.default_rng(3)
    for _ in range(400):
        x = rng.uniform(LO, HI)
        x[0] = 1.0
        got = x.copy()
        d = refine.pelvis_projection(got, data, LO, HI)
        assert d == unpruned(x, data)
        assert got[L.X_TBD] == x[L.X_TBD] + d and got[L.X_TTR] == x[L.X_TTR] - d


def test_moves_no_landmark_and_lowers_the_prior():
    data = _data(FitConfig())
    rng = np.random.default_rng(4)
    from posed.fitting import forward_kinematics as FK
    for _ in range(50):
        x = rng.uniform(LO, HI) * 0.5
        x[0] = 1.0
        y = x.copy()
        refine.pelvis_projection(y, data, LO, HI)
        assert refine.data_mse(y, data) == pytest.approx(refine.data_mse(x, data), abs=1e-12)
        before = refine._prior_along(x, 0.0, data, LO, HI, FK.torso_uprightness(x))
        after = refine._prior_along(y, 0.0, data, LO, HI, FK.torso_uprightness(y))
        assert after <= before + 1e-12
