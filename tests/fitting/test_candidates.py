"""Image mode's candidates kernel (fitting.candidates.image_candidates) against the Python loop it replaced, to
the last bit, with an exact fit (which ends the search) and without, with and without limb mirrors."""

import numpy as np
import pytest

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.candidates import LIMB_JOINT, image_candidates, score_all, score_into
from posed.fitting.fitter import EXACT_MSE, STRAIGHT_RAD
from posed.fitting.loss import pose_loss_terms

from .test_hypotheses import _problem

LO, HI = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD


def reference_score(x, data, work):
    """The pelvis tilt set by its prior, then the loss: (x, loss, 2D error)."""
    out = x.copy()
    refine.pelvis_projection(out, data, LO, HI)
    loss, mp = pose_loss_terms(out, data, work)[:2]
    return out, float(loss), float(mp)


def reference_candidates(picked, data, work, trial_its, its, finalists, passes):
    """The Python loop of Fitter._image before the kernel: (pool, scored, mse) as lists."""
    def lm(x, n):
        out = np.empty(L.N_VAR)
        return out, float(refine.levenberg_marquardt(x, LO, HI, data, n, out)[0])

    pool, costs, mse = [], [], []
    exact = False
    for cand in picked:
        x, cost = lm(cand, trial_its)
        pool.append(x)
        costs.append(cost)
        mse.append(refine.data_mse(x, data))
        if mse[-1] < EXACT_MSE:
            exact = True
            pool[-1] = lm(x, its)[0]
            mse[-1] = refine.data_mse(pool[-1], data)
            break
    if not exact:
        for i in sorted(range(len(pool)), key=costs.__getitem__)[:finalists]:
            pool[i] = lm(pool[i], its)[0]
            mse[i] = refine.data_mse(pool[i], data)
            if mse[i] < EXACT_MSE:
                exact = True
                break
    scored = [reference_score(x, data, work) for x in pool]
    if passes == 0:
        return pool, scored, mse
    lead, lead_loss = min(scored, key=lambda s: s[1])[:2]
    trial = np.empty(L.N_VAR)
    tried = set()
    for _ in range(passes):
        improved = False
        for limb in range(4):
            if exact and abs(lead[LIMB_JOINT[limb]]) > STRAIGHT_RAD:
                continue
            refine.limb_flip(lead, data, limb, trial)
            key = (np.round(trial, 3) + 0.0).tobytes()
            if key in tried:
                continue
            tried.add(key)
            x = lm(trial, its)[0]
            pool.append(x)
            mse.append(refine.data_mse(x, data))
            scored.append(reference_score(x, data, work))
            if scored[-1][1] < lead_loss:
                lead, lead_loss = scored[-1][:2]
                improved = True
        if not improved:
            break
    return pool, scored, mse


def run_kernel(picked, data, work, trial_its, its, finalists, passes):
    cap = len(picked) + 4 * passes
    pool, scored = np.full((cap, L.N_VAR), np.nan), np.full((cap, L.N_VAR), np.nan)
    loss, mp, mse = np.full(cap, np.nan), np.full(cap, np.nan), np.full(cap, np.nan)
    n = image_candidates(picked, LO, HI, data, work, trial_its, its, finalists, passes, EXACT_MSE, STRAIGHT_RAD,
                         pool, scored, loss, mp, mse)
    return n, pool, scored, loss, mp, mse


@pytest.mark.parametrize("noise_px, seed, perspective", [(0.0, 1, False), (0.0, 1, True), (3.0, 2, True),
                                                         (8.0, 3, True)])
@pytest.mark.parametrize("trial_its, finalists, passes", [(5, 2, 2), (3, 1, 1), (30, 4, 0), (2, 50, 3)])
def test_kernel_matches_the_python_loop(noise_px, seed, perspective, trial_its, finalists, passes):
    frame, starts = _problem(noise_px, seed, perspective)
    want_pool, want_scored, want_mse = reference_candidates(starts, frame.data, FK.empty_work(), trial_its, 30,
                                                            finalists, passes)
    n, pool, scored, loss, mp, mse = run_kernel(starts, frame.data, FK.empty_work(), trial_its, 30, finalists,
                                                passes)
    assert n == len(want_pool)
    np.testing.assert_array_equal(pool[:n], np.array(want_pool))
    np.testing.assert_array_equal(mse[:n], np.array(want_mse))
    np.testing.assert_array_equal(scored[:n], np.array([s[0] for s in want_scored]))
    np.testing.assert_array_equal(loss[:n], np.array([s[1] for s in want_scored]))
    np.testing.assert_array_equal(mp[:n], np.array([s[2] for s in want_scored]))
    assert np.isnan(pool[n:]).all()   # nothing written past the count


def test_an_exact_trial_ends_the_search():
    """Noise-free and orthographic the first analytic start is exact: nothing after it is refined."""
    frame, starts = _problem(0.0, 1, perspective=False)
    n, pool, _, loss, _, mse = run_kernel(starts, frame.data, FK.empty_work(), 5, 30, 2, 0)
    assert mse[n - 1] < EXACT_MSE
    assert n < len(starts)


def test_score_all_and_score_into_match_the_reference():
    frame, starts = _problem(3.0, 2)
    work = FK.empty_work()
    scored, loss, mp = np.empty_like(starts), np.empty(len(starts)), np.empty(len(starts))
    score_all(starts, len(starts), frame.data, LO, HI, work, scored, loss, mp)
    for i, x in enumerate(starts):
        want = reference_score(x, frame.data, FK.empty_work())
        np.testing.assert_array_equal(scored[i], want[0])
        assert (loss[i], mp[i]) == want[1:]
        out = np.empty(L.N_VAR)
        assert score_into(x, frame.data, LO, HI, work, out) == want[1:]
        np.testing.assert_array_equal(out, want[0])
