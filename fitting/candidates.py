"""Image mode's candidates of one frame: refined, their limb mirrors tried, each scored. numba, ``cache=True``.

:func:`image_candidates` is the part of ``Fitter._image`` between uDEAS and the choice under the pose prior
(``Fitter._select``): every start ranked by a few Levenberg-Marquardt iterations, the best refined to
convergence (an exact fit ends the search), then each limb's depth mirror of the best so far refined and kept
when its loss is lower. One call per frame: the Python loop it replaces cost about 0.1 ms a frame in
interpreter overhead on the out-of-domain protocol (5-8 % of image mode); tested against that loop (the
reference in ``tests/fitting/test_candidates.py``). Kernel units (radians; gamma unitless; 2D in the packed
data's normalized units).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.loss import pose_loss_terms
from posed.fitting.refine import data_mse, levenberg_marquardt_into, limb_flip, lm_work, pelvis_projection

# the joint whose flexion tells whether a limb is bent, per limb (refine.LIMB_* order: the arms, then the legs)
LIMB_JOINT = np.array([L.X_TEL_L, L.X_TEL_R, L.X_TKN_L, L.X_TKN_R])


@njit(cache=True)
def score_into(x, data, lo, hi, work, out):
    """``out`` = ``x`` with the pelvis tilt set by its prior (refine.pelvis_projection in the box
    ``lo``..``hi``); returns (its loss, its 2D error) (fitting.loss.pose_loss_terms)."""
    for j in range(L.N_VAR):
        out[j] = x[j]
    pelvis_projection(out, data, lo, hi)
    terms = pose_loss_terms(out, data, work)
    return terms[0], terms[1]


@njit(cache=True)
def score_all(pool, n, data, lo, hi, work, scored, loss, mp):
    """:func:`score_into` of the first ``n`` rows of ``pool``: ``scored``, ``loss`` and ``mp`` rows 0..n-1."""
    for i in range(n):
        loss[i], mp[i] = score_into(pool[i], data, lo, hi, work, scored[i])


@njit(cache=True)
def _key_seen(tried, n_tried, key):
    """Whether ``key`` equals one of the first ``n_tried`` rows of ``tried``."""
    for t in range(n_tried):
        same = True
        for j in range(L.N_VAR):
            if tried[t, j] != key[j]:
                same = False
                break
        if same:
            return True
    return False


@njit(cache=True)
def image_candidates(picked, lo, hi, data, work, trial_iterations, iterations, finalists, mirror_passes,
                     exact_mse, straight_rad, pool, scored, loss, mp, mse):
    """Refine the starts ``picked`` (k x 19) on ``data`` in the box ``lo``..``hi`` and write the candidates:
    ``pool`` (refined, capacity k + 4 ``mirror_passes`` rows), ``scored`` (each with its pelvis tilt set by
    the prior), ``loss`` and ``mp`` (:func:`score_into` of each), ``mse`` (refine.data_mse of each). Returns
    how many were written.

    Every start gets ``trial_iterations`` iterations; a trial with a mean squared 2D error under
    ``exact_mse`` is exact: refined to convergence (``iterations``) and the other starts skipped; else the
    ``finalists`` smallest costs (ties: the earlier start) are refined to convergence, stopping at the first
    exact one. Then, ``mirror_passes`` times at most (again only after an improvement), each limb's depth
    mirror of the best-scored candidate so far (refine.limb_flip; a start already tried, rounded to 0.001,
    is skipped; after an exact fit the mirrors of limbs bent more than ``straight_rad`` too, as they cannot
    fit exactly) refined to convergence, and the best so far replaced when its loss is lower.
    ``work``: the loss's work array (fitting.forward_kinematics.empty_work)."""
    k = picked.shape[0]
    lw = lm_work()
    costs = np.empty(k)
    n = 0
    exact = False
    for c in range(k):
        costs[n] = levenberg_marquardt_into(picked[c], lo, hi, data, trial_iterations, pool[n], lw)[0]
        mse[n] = data_mse(pool[n], data)
        n += 1
        if mse[n - 1] < exact_mse:
            exact = True  # an exact fit: the other candidates cannot fit better
            levenberg_marquardt_into(pool[n - 1], lo, hi, data, iterations, pool[n - 1], lw)
            mse[n - 1] = data_mse(pool[n - 1], data)
            break
    if not exact:
        order = np.argsort(costs[:n], kind="mergesort")   # stable: ties keep the starts' order
        for r in range(min(finalists, n)):
            i = order[r]
            levenberg_marquardt_into(pool[i], lo, hi, data, iterations, pool[i], lw)
            mse[i] = data_mse(pool[i], data)
            if mse[i] < exact_mse:
                exact = True
                break
    score_all(pool, n, data, lo, hi, work, scored, loss, mp)
    if mirror_passes <= 0 or n == 0:
        return n
    lead_i = np.argmin(loss[:n])
    lead = scored[lead_i].copy()
    lead_loss = loss[lead_i]
    trial = np.empty(L.N_VAR)
    tried = np.empty((4 * mirror_passes, L.N_VAR))
    n_tried = 0
    for _ in range(mirror_passes):
        improved = False
        for limb in range(4):
            if exact and abs(lead[LIMB_JOINT[limb]]) > straight_rad:
                continue  # the mirror of a bent limb cannot fit exactly: it cannot tie with an exact fit
            limb_flip(lead, data, limb, trial)
            key = np.round(trial, 3)
            if _key_seen(tried, n_tried, key):
                continue
            tried[n_tried] = key
            n_tried += 1
            levenberg_marquardt_into(trial, lo, hi, data, iterations, pool[n], lw)
            mse[n] = data_mse(pool[n], data)
            loss[n], mp[n] = score_into(pool[n], data, lo, hi, work, scored[n])
            n += 1
            if loss[n - 1] < lead_loss:
                lead[:] = scored[n - 1]
                lead_loss = loss[n - 1]
                improved = True
        if not improved:
            break
    return n
