"""numba kernels: the joint-range penalties of the paper's section 4.2 (eqs. 9-11) and, for the
least-squares refinement, the same penalties as hinge residuals together with the joint-limit hinges and the
pose-prior rows, with their Jacobian rows. ``cache=True``; angles in radians.

Tested against NumPy references in ``tests/fitting/test_loss.py`` (the loss sum) and
``tests/fitting/test_kinematics.py`` (the residual rows and the Jacobian, against finite differences).
"""

from __future__ import annotations

import math

from numba import njit

from posed.fitting import layout as L


@njit(cache=True)
def p_sn(a, sigma):
    """Single-sided negative penalty, eq. (9): how far ``a`` is below ``sigma``."""
    return sigma - a if a < sigma else 0.0


@njit(cache=True)
def p_sp(a, sigma):
    """Single-sided positive penalty, eq. (10): how far ``a`` is above ``sigma``."""
    return a - sigma if a > sigma else 0.0


@njit(cache=True)
def p_d(a, lo, hi):
    """Double-sided penalty, eq. (11): how far ``a`` is outside [lo, hi)."""
    if a < lo:
        return lo - a
    if a >= hi:
        return a - hi
    return 0.0


@njit(cache=True)
def penalties(x, data):
    """Weighted sum of the paper's penalty terms (section 4.2) and the hip-adduction term, for the loss."""
    w = L.D_LW
    th = L.D_TH
    acc = data[w + L.LW_SAG_TR] * p_sn(x[L.X_TTR], data[th + L.TH_TR_FLEX_MIN])
    acc += data[w + L.LW_COR_TR] * p_d(x[L.X_PTR], -data[th + L.TH_TR_LATERAL], data[th + L.TH_TR_LATERAL])
    acc += data[w + L.LW_TRAN_TR] * p_d(x[L.X_STR], -data[th + L.TH_TR_TWIST], data[th + L.TH_TR_TWIST])
    acc += data[w + L.LW_SAG_SH] * (p_sn(x[L.X_TSH_L], data[th + L.TH_SH_FLEX_MIN])
                                  + p_sn(x[L.X_TSH_R], data[th + L.TH_SH_FLEX_MIN]))
    acc += data[w + L.LW_COR_SH] * (p_sp(x[L.X_PSH_L], data[th + L.TH_SH_ADD_MAX])
                                  + p_sp(x[L.X_PSH_R], data[th + L.TH_SH_ADD_MAX]))
    acc += data[w + L.LW_COR_HP] * (p_sp(x[L.X_PHP_L], data[th + L.TH_HP_ADD_MAX])
                                  + p_sp(x[L.X_PHP_R], data[th + L.TH_HP_ADD_MAX]))
    return acc


# --- least-squares form: one hinge residual per penalty term ---

BELOW, OUTSIDE, ABOVE = 0, 1, 2  # p_sn(a, t), p_d(a, -t, t), p_sp(a, t)

# (variable, loss weight LW_*, threshold TH_*, kind) of residual row R_PEN + q
PENALTY_HINGES = (
    (L.X_TTR, L.LW_SAG_TR, L.TH_TR_FLEX_MIN, BELOW),
    (L.X_PTR, L.LW_COR_TR, L.TH_TR_LATERAL, OUTSIDE),
    (L.X_STR, L.LW_TRAN_TR, L.TH_TR_TWIST, OUTSIDE),
    (L.X_TSH_L, L.LW_SAG_SH, L.TH_SH_FLEX_MIN, BELOW),
    (L.X_TSH_R, L.LW_SAG_SH, L.TH_SH_FLEX_MIN, BELOW),
    (L.X_PSH_L, L.LW_COR_SH, L.TH_SH_ADD_MAX, ABOVE),
    (L.X_PSH_R, L.LW_COR_SH, L.TH_SH_ADD_MAX, ABOVE),
    (L.X_PHP_L, L.LW_COR_HP, L.TH_HP_ADD_MAX, ABOVE),
    (L.X_PHP_R, L.LW_COR_HP, L.TH_HP_ADD_MAX, ABOVE),
)
assert len(PENALTY_HINGES) == L.N_PEN


@njit(cache=True)
def _hinge(kind, a, t):
    """(penalty of ``a`` against threshold ``t``, its slope d penalty / d a where it is positive)."""
    if kind == BELOW:
        return p_sn(a, t), -1.0
    if kind == OUTSIDE:
        return p_d(a, -t, t), (-1.0 if a < 0 else 1.0)
    return p_sp(a, t), 1.0


@njit(cache=True)
def _prior_scale(data):
    """sqrt(lambda) of the pose prior (0 = off)."""
    return math.sqrt(data[L.D_PRIOR]) if data[L.D_PRIOR] > 0.0 else 0.0


@njit(cache=True)
def hinge_residuals(x, data, res):
    """Residual rows R_PEN.. (sqrt(weight) times each penalty), R_LIM.. (sqrt(limit weight) times the distance
    outside the joint limits), R_PRIOR.. (sqrt(lambda) (x_k - x_partner - mu_k) / sigma_k, or 0) and R_FLEX..
    (w_h (x_k - flex_h) for the hinge k = FLEX_VARS[h], or 0)."""
    for q in range(L.N_PEN):
        k, lw, th, kind = PENALTY_HINGES[q]
        res[L.R_PEN + q] = math.sqrt(data[L.D_LW + lw]) * _hinge(kind, x[k], data[L.D_TH + th])[0]
    w_lim = math.sqrt(data[L.D_LW + L.LW_LIMIT])
    for k in range(L.N_VAR):
        res[L.R_LIM + k] = w_lim * p_d(x[k], data[L.D_LIM_LO + k], data[L.D_LIM_HI + k])
    lam = _prior_scale(data)
    for k in range(L.N_VAR):
        sig = data[L.D_PRIOR_SIG + k]
        if sig > 0.0 and lam > 0.0:
            p = int(data[L.D_PRIOR_PARTNER + k])
            v = x[k] - (x[p] if p >= 0 else 0.0)
            res[L.R_PRIOR + k] = lam * (v - data[L.D_PRIOR_MU + k]) / sig
        else:
            res[L.R_PRIOR + k] = 0.0
    for h in range(L.N_FLEX):
        res[L.R_FLEX + h] = data[L.D_FLEX_W + h] * (x[L.FLEX_VARS[h]] - data[L.D_FLEX + h])


@njit(cache=True)
def hinge_jacobian(x, data, jac):
    """Rows R_PEN .. R_FLEX + N_FLEX - 1 of d res / d x (see hinge_residuals); every other entry zero."""
    for q in range(L.R_PEN, L.R_FLEX + L.N_FLEX):
        for k in range(L.N_VAR):
            jac[q, k] = 0.0
    for q in range(L.N_PEN):
        k, lw, th, kind = PENALTY_HINGES[q]
        value, slope = _hinge(kind, x[k], data[L.D_TH + th])
        if value > 0.0:
            jac[L.R_PEN + q, k] = math.sqrt(data[L.D_LW + lw]) * slope
    w_lim = math.sqrt(data[L.D_LW + L.LW_LIMIT])
    for k in range(L.N_VAR):
        v = x[k]
        if v < data[L.D_LIM_LO + k]:
            jac[L.R_LIM + k, k] = -w_lim
        elif v >= data[L.D_LIM_HI + k]:
            jac[L.R_LIM + k, k] = w_lim
    lam = _prior_scale(data)
    for q in range(L.N_VAR):
        sig = data[L.D_PRIOR_SIG + q]
        if sig > 0.0 and lam > 0.0:
            jac[L.R_PRIOR + q, q] = lam / sig
            p = int(data[L.D_PRIOR_PARTNER + q])
            if p >= 0:
                jac[L.R_PRIOR + q, p] = -lam / sig
    for h in range(L.N_FLEX):
        jac[L.R_FLEX + h, L.FLEX_VARS[h]] = data[L.D_FLEX_W + h]
