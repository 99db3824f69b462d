"""Video mode's hypotheses of one frame and the choice between them. numba, ``cache=True``.

:func:`video_starts`: the previous solution moved to the frame, each limb's depth mirror of it and the frame's
analytic starts. :func:`best_hypothesis`: each refined a few Levenberg-Marquardt iterations to rank them, the
best few to convergence, the smallest cost wins (MAP over the hypotheses; image mode's best candidates under
the pose prior are chosen the same way when there is no depth).

With measured depth each refinement carries the depth rows (fitting.depth_rows) with robust weights solved
from its own start (again from the trial's result for the finalists), and the candidates are compared on
:func:`fitting.depth_rows.cost_with_depth`; without, on the refinement's own cost. One call per frame: the
Python loop it replaces cost about as much as a refinement (tested against it in
``tests/fitting/test_hypotheses.py``). Kernel units (radians; gamma unitless).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.analytic import analytic_start
from posed.fitting.depth_rows import cost_with_depth, set_depth_rows_at
from posed.fitting.refine import levenberg_marquardt_into, limb_flip, lm_work


@njit(cache=True)
def _refined(x0, lo, hi, data, depth, sensor, use_depth, w_depth, iterations, out, lw):
    """``out`` = ``x0`` refined on ``data`` (its depth rows set from ``x0`` when ``use_depth``; ``lw`` the
    refinement's work arrays, fitting.refine.lm_work); returns the cost the candidates are compared on."""
    if use_depth:
        set_depth_rows_at(x0, data, depth, sensor, w_depth)
    cost = levenberg_marquardt_into(x0, lo, hi, data, iterations, out, lw)[0]
    if use_depth:
        cost = cost_with_depth(out, data, depth, sensor, w_depth)
    return cost


@njit(cache=True)
def best_hypothesis(starts, lo, hi, data, depth, sensor, use_depth, w_depth, trial_iterations, iterations,
                    finalists, out):
    """``out`` (19) = the best of the hypotheses ``starts`` (k x 19) on ``data`` (the frame's packed array with
    its prior rows set; its depth rows are overwritten when ``use_depth``): every start refined
    ``trial_iterations``, the ``finalists`` smallest (ties: the earlier start) refined again up to
    ``iterations``, the smallest compared cost (ties: the better-ranked) wins. ``depth``: the measured depth at
    the 12 body landmarks (metres, NaN unknown) of the ``sensor`` (fitting.depth_term), used only when
    ``use_depth``; ``w_depth``: the depth term's
    weight in the refinement's cost units. Returns the winner's compared cost (without starts: inf, ``out``
    NaN)."""
    k = starts.shape[0]
    if k == 0:
        for j in range(L.N_VAR):
            out[j] = np.nan
        return np.inf
    trials = np.empty((k, L.N_VAR))
    costs = np.empty(k)
    lw = lm_work()
    for i in range(k):
        costs[i] = _refined(starts[i], lo, hi, data, depth, sensor, use_depth, w_depth, trial_iterations,
                            trials[i], lw)
    order = np.argsort(costs, kind="mergesort")   # stable: ties keep the starts' order
    best = np.inf
    cand = np.empty(L.N_VAR)
    for r in range(min(finalists, k)):
        c = _refined(trials[order[r]], lo, hi, data, depth, sensor, use_depth, w_depth, iterations, cand, lw)
        if r == 0 or c < best:
            best = c
            for j in range(L.N_VAR):
                out[j] = cand[j]
    return best


@njit(cache=True)
def video_starts(start, seeds, mirrors, data, work, out):
    """``out`` rows 0 .. 1 + ``mirrors`` + len(``seeds``) - 1: ``start``; the depth mirror of each of its first
    ``mirrors`` limbs (fitting.refine.limb_flip, LIMB_* order); the analytic start of each orientation seed
    (fitting.analytic). ``work``: the loss's work array."""
    for k in range(L.N_VAR):
        out[0, k] = start[k]
    for limb in range(mirrors):
        limb_flip(start, data, limb, out[1 + limb])
    for i in range(seeds.shape[0]):
        analytic_start(seeds[i], data, work, out[1 + mirrors + i])
