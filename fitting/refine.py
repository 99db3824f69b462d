"""Local refinement after uDEAS, the pelvis-tilt (null-space) projection and the limb hypotheses. numba,
``cache=True``.

* :func:`levenberg_marquardt`: minimizes the sum of squared residuals of
  :func:`fitting.jacobian.residuals_jacobian` (weighted mean squared 2D error plus squared penalty hinges,
  plus the prior rows when the prior weight is set) with Marquardt's diagonal damping, clamping every
  variable to the joint limits; its normal equations (:func:`normal_equations`: dense landmark and depth
  rows, sparse hinge and prior rows) and damped Cholesky solve (:func:`cholesky_solve_into`) use work arrays
  (:func:`lm_work`), and so do the residuals and the Jacobian (:func:`fitting.jacobian.residuals_into`,
  :func:`fitting.jacobian.jacobian_into`): an accepted trial's residuals are kept and only its Jacobian
  computed. :func:`levenberg_marquardt` allocates them per refinement; a caller that refines many starts
  allocates them once and calls :func:`levenberg_marquardt_into`.
* :func:`pelvis_projection`: moves along the exact null direction (theta_bd + d, theta_tr - d,
  theta_hp_l + d, theta_hp_r + d), which changes no landmark, to the minimum of the pelvis-tilt prior.
* :func:`limb_from_observation` / :func:`limb_flip`: a limb solved from its 2D landmarks for a chosen depth
  sign of its upper segment (analytic starts; the depth mirror of trap 2).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import forward_kinematics as FK
from posed.fitting import jacobian as JAC
from posed.fitting import layout as L
from posed.fitting import penalties as PEN
from posed.fitting import rotations as ROT

REL_TOL = 1e-3  # LM stops when an accepted step lowers the cost by less than this fraction of it


@njit(cache=True)
def cholesky_solve(a, b, out):
    """Solve a out = b for a symmetric positive definite ``a`` (n x n); returns False if not SPD."""
    n = a.shape[0]
    return cholesky_solve_into(a, b, out, np.empty((n, n)), np.empty(n))


@njit(cache=True)
def cholesky_solve_into(a, b, out, low, y):
    """:func:`cholesky_solve` with caller work arrays ``low`` (n x n: its strict lower triangle overwritten
    with the Cholesky factor L, its diagonal with 1 / L_ii) and ``y`` (n): no allocation, for the
    refinement's inner loop. Only the lower triangle of ``a`` is read; divisions are multiplications by the
    reciprocal diagonal."""
    n = a.shape[0]
    for i in range(n):
        for j in range(i):
            acc = a[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            low[i, j] = acc * y[j]
        acc = a[i, i]
        for k in range(i):
            acc -= low[i, k] * low[i, k]
        if not acc > 0.0:
            return False
        low[i, i] = math.sqrt(acc)
        y[i] = 1.0 / low[i, i]  # the reciprocal diagonal until the solve below overwrites y
    for i in range(n):
        low[i, i] = y[i]
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc -= low[i, k] * y[k]
        y[i] = acc * low[i, i]
    for i in range(n - 1, -1, -1):
        acc = y[i]
        for k in range(i + 1, n):
            acc -= low[k, i] * out[k]
        out[i] = acc * low[i, i]
    return True


@njit(cache=True)
def _dense_rows(jac, res, r0, r1, a, g):
    """Add rows r0 .. r1 - 1 of J to the lower triangle of a = J'J and to g = J'r, column by column of each
    row's non-zero entries (a landmark row has none for the limbs it does not depend on)."""
    n = jac.shape[1]
    for r in range(r0, r1):
        rr = res[r]
        for i in range(n):
            ji = jac[r, i]
            if ji == 0.0:
                continue
            g[i] += ji * rr
            for j in range(i + 1):
                a[i, j] += ji * jac[r, j]


@njit(cache=True)
def _sparse_rows(jac, res, r0, r1, a, g, cols):
    """:func:`_dense_rows` for rows with few non-zeros: each row's non-zero columns are found first
    (``cols``, int64 work array) and only their products added, in the same order (the same sums: the
    products left out are zeros)."""
    n = jac.shape[1]
    for r in range(r0, r1):
        nz = 0
        for i in range(n):
            if jac[r, i] != 0.0:
                cols[nz] = i
                nz += 1
        if nz == 0:
            continue
        rr = res[r]
        for p in range(nz):
            i = cols[p]
            ji = jac[r, i]
            g[i] += ji * rr
            for q in range(p + 1):
                a[i, cols[q]] += ji * jac[r, cols[q]]


@njit(cache=True)
def normal_equations(jac, res, a, g, cols):
    """a = J'J and g = J'r (half the cost's gradient) of the refinement's residual rows (layout R_*) into
    ``a`` (n x n, both triangles) and ``g`` (n), summed over the rows in ascending order.

    The landmark rows are dense (with a pinhole camera every landmark depends on every variable through the
    solved translation); the penalty and joint-limit rows after them have at most one non-zero, in the
    column of their variable (:func:`fitting.penalties.hinge_jacobian`); the prior rows have one or two, a
    flexion row one, and a depth row those of its landmark's chain (none without depth), found per row
    (:func:`_sparse_rows`).
    ``cols``: int64 work array (n)."""
    n = jac.shape[1]
    for i in range(n):
        g[i] = 0.0
        for j in range(n):
            a[i, j] = 0.0
    _dense_rows(jac, res, L.R_LM, L.R_PEN, a, g)
    # a penalty or joint-limit hinge row has its one possible non-zero in its variable's column
    for q in range(L.N_PEN + L.N_VAR):
        i = PEN.PENALTY_HINGES[q][0] if q < L.N_PEN else q - L.N_PEN
        ji = jac[L.R_PEN + q, i]
        if ji != 0.0:
            g[i] += ji * res[L.R_PEN + q]
            a[i, i] += ji * ji
    _sparse_rows(jac, res, L.R_PRIOR, L.N_RES, a, g, cols)
    for i in range(n):
        for j in range(i):
            a[j, i] = a[i, j]


@njit(cache=True)
def lm_work():
    """Work arrays of :func:`levenberg_marquardt_into`, reusable from refinement to refinement (a caller that
    refines many starts allocates them once): residuals and Jacobian (two residual vectors, swapped between
    the current point and a trial), their work arrays (fitting.jacobian.empty_work), the point and its trial,
    the normal equations, their damped copy and Cholesky factor, the step and the active set."""
    n = L.N_VAR
    m = JAC.n_residuals()
    return (np.empty(m), np.empty((m, n)), np.empty(m), JAC.empty_work(), np.empty(n), np.empty(n),
            np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty(n), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n, dtype=np.bool_), np.empty(n, dtype=np.int64))


@njit(cache=True)
def levenberg_marquardt(x0, lo, hi, data, max_iter, out_x):
    """Refine ``x0`` inside [lo, hi]; returns (final sum of squares, iterations, evaluations: the start, each
    trial and each accepted point's Jacobian).

    Marquardt's diagonal damping with the gain-ratio update of Nielsen (the damping shrinks after a step the
    linear model predicted well and grows 2, 4, 8 ... times after rejected ones); a variable at a bound whose
    descent direction leaves the box is held there for the iteration (an active set), so clamped steps are
    not rejected over and over; stops when an accepted step lowers the cost by less than REL_TOL of it."""
    return levenberg_marquardt_into(x0, lo, hi, data, max_iter, out_x, lm_work())


@njit(cache=True)
def levenberg_marquardt_into(x0, lo, hi, data, max_iter, out_x, lw):
    """:func:`levenberg_marquardt` on the work arrays ``lw`` (:func:`lm_work`): no allocation."""
    res, jac, res_new, work, x, x_new, a, damped, low, g, rhs, step, y_work, held, cols = lw
    n = x0.size
    for k in range(n):
        x[k] = min(max(x0[k], lo[k]), hi[k])
    JAC.residuals_into(x, data, res, work)
    JAC.jacobian_into(x, data, jac, work)
    cost = JAC.sum_sq(res)
    evals = 1
    lam = 1e-3
    nu = 2.0
    it = 0
    while it < max_iter:
        it += 1
        # normal equations: a = J'J, g = J'r (half the cost's gradient)
        normal_equations(jac, res, a, g, cols)
        for i in range(n):
            held[i] = (x[i] <= lo[i] and g[i] > 0.0) or (x[i] >= hi[i] and g[i] < 0.0)
        # the damped matrix's off-diagonal lower triangle and the right-hand side are the same for every trial
        for i in range(n):
            rhs[i] = 0.0 if held[i] else -g[i]
            for j in range(i):
                damped[i, j] = 0.0 if (held[i] or held[j]) else a[i, j]
        improved = False
        c_new = cost
        for _ in range(12):
            for i in range(n):
                damped[i, i] = 1.0 if held[i] else a[i, i] + lam * max(a[i, i], 1e-9) + 1e-12
            if not cholesky_solve_into(damped, rhs, step, low, y_work):
                lam *= nu
                nu *= 2.0
                continue
            for k in range(n):
                x_new[k] = min(max(x[k] + step[k], lo[k]), hi[k])
            JAC.residuals_into(x_new, data, res_new, work)
            evals += 1
            c_new = JAC.sum_sq(res_new)
            if c_new < cost:
                improved = True
                # gain ratio: the actual reduction over the linear model's, for the (clamped) step taken
                pred = 0.0
                for i in range(n):
                    h = x_new[i] - x[i]
                    acc = 0.0
                    for j in range(n):
                        acc += a[i, j] * (x_new[j] - x[j])
                    pred -= h * (2.0 * g[i] + acc)
                rho = (cost - c_new) / pred if pred > 0.0 else 0.0
                lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-9)
                nu = 2.0
                break
            lam *= nu
            nu *= 2.0
        if not improved:
            break
        gain = cost - c_new
        for k in range(n):
            x[k] = x_new[k]
        cost = c_new
        # the accepted trial was the last evaluation: its residuals and work arrays are those of x
        res, res_new = res_new, res
        JAC.jacobian_into(x, data, jac, work)
        evals += 1
        if gain <= 1e-13 + REL_TOL * cost:
            break
    for k in range(n):
        out_x[k] = x[k]
    return cost, it, evals


@njit(cache=True)
def data_mse(x, data):
    """Weighted mean squared 2D residual of the landmarks (normalized units squared)."""
    res = np.empty(JAC.n_residuals())
    dummy = np.empty((1, 1))
    JAC.residuals_jacobian(x, data, res, dummy, False)
    acc = 0.0
    for i in range(2 * L.N_LM):
        acc += res[i] * res[i]
    return acc


@njit(cache=True)
def _prior_linear(x, d, data):
    """The lumbar and hip part of :func:`_prior_along` (its first sum; the rest only adds to it)."""
    lw = L.D_LW
    return (data[lw + L.LW_PRIOR_TR] * abs(x[L.X_TTR] - d)
            + data[lw + L.LW_PRIOR_HP] * (abs(x[L.X_THP_L] + d) + abs(x[L.X_THP_R] + d)))


@njit(cache=True)
def _prior_along(x, d, data, lim_lo, lim_hi, upright):
    lw = L.D_LW
    t_tr = x[L.X_TTR] - d
    t_hl = x[L.X_THP_L] + d
    t_hr = x[L.X_THP_R] + d
    t_bd = x[L.X_TBD] + d
    up = data[lw + L.LW_PRIOR_UP] * upright
    c = math.cos(t_bd) * math.cos(x[L.X_PBD])
    c = min(max(c, -1.0), 1.0)
    acc = _prior_linear(x, d, data)
    acc += up * math.acos(c)
    # the paper's lumbar penalty and the joint limits keep the choice plausible
    acc += data[lw + L.LW_SAG_TR] * 100.0 * PEN.p_sn(t_tr, data[L.D_TH])
    big = 1000.0
    acc += big * (PEN.p_d(t_tr, lim_lo[L.X_TTR], lim_hi[L.X_TTR]) + PEN.p_d(t_hl, lim_lo[L.X_THP_L], lim_hi[L.X_THP_L])
                  + PEN.p_d(t_hr, lim_lo[L.X_THP_R], lim_hi[L.X_THP_R]) + PEN.p_d(t_bd, lim_lo[L.X_TBD], lim_hi[L.X_TBD]))
    return acc


@njit(cache=True)
def pelvis_projection(x, data, lim_lo, lim_hi):
    """The d minimizing the pelvis-tilt prior along the null direction; ``x`` is updated in place.

    A 1-degree grid over [-180, 180] degrees and the prior's breakpoints, then a golden-section polish around
    the best; a point whose lumbar and hip part alone is no lower than the best so far is not evaluated
    further (the rest of the prior only adds to it, so the choice is the same: about 3x faster)."""
    # the torso's orientation does not change along the null direction
    upright = FK.torso_uprightness(x)
    best_d = 0.0
    best = _prior_along(x, 0.0, data, lim_lo, lim_hi, upright)
    # every term after the linear part adds a non-negative amount (non-negative weights): a point whose linear
    # part alone is no better than the best cannot win, and is not evaluated further (the same choice)
    lw = L.D_LW
    bound = (data[lw + L.LW_PRIOR_UP] >= 0.0 and data[lw + L.LW_SAG_TR] >= 0.0)
    step = math.pi / 180.0
    d = -math.pi
    while d <= math.pi:
        if not (bound and _prior_linear(x, d, data) >= best - 1e-12):
            c = _prior_along(x, d, data, lim_lo, lim_hi, upright)
            if c < best - 1e-12:
                best = c
                best_d = d
        d += step
    # the minimum of a piecewise-linear prior sits on a breakpoint: try them exactly
    for cand in (x[L.X_TTR], -x[L.X_THP_L], -x[L.X_THP_R], -x[L.X_TBD]):
        if bound and _prior_linear(x, cand, data) >= best - 1e-12:
            continue
        c = _prior_along(x, cand, data, lim_lo, lim_hi, upright)
        if c < best - 1e-12:
            best = c
            best_d = cand
    # golden-section polish around the best grid point (the tilt term is smooth when phi_bd != 0)
    a = best_d - step
    b = best_d + step
    gr = 0.6180339887498949
    for _ in range(30):
        c1 = b - gr * (b - a)
        c2 = a + gr * (b - a)
        if _prior_along(x, c1, data, lim_lo, lim_hi, upright) < _prior_along(x, c2, data, lim_lo, lim_hi, upright):
            b = c2
        else:
            a = c1
    mid = 0.5 * (a + b)
    if _prior_along(x, mid, data, lim_lo, lim_hi, upright) < best - 1e-12:
        best_d = mid
    x[L.X_TBD] += best_d
    x[L.X_TTR] -= best_d
    x[L.X_THP_L] += best_d
    x[L.X_THP_R] += best_d
    return best_d


LIMB_ARM_L, LIMB_ARM_R, LIMB_LEG_L, LIMB_LEG_R = 0, 1, 2, 3


@njit(cache=True)
def _mt_v(r, v0, v1, v2):
    """r^T v for a row-major 9-tuple r."""
    return (r[0] * v0 + r[3] * v1 + r[6] * v2, r[1] * v0 + r[4] * v1 + r[7] * v2,
            r[2] * v0 + r[5] * v1 + r[8] * v2)


STRAIGHT_ARM = math.sin(math.radians(10.0))   # an elbow bent less than this leaves its rotation undefined


@njit(cache=True)
def _arm_rotation(r_up, v0, v1, v2, s, lo, hi, out, xj, x_psi):
    """With the upper arm's rotation free (limits ``lo`` < ``hi``): the elbow flexion and rotation that put the
    forearm exactly on its observed direction (``v0, v1`` in the image, ``+-v2`` in depth; unit length), of the
    two depth signs the one with the rotation nearer neutral within the limits, into ``out``. In the upper
    arm's frame before its rotation (``r_up``) the forearm is Rz(-s psi) (sin theta_el, 0, -cos theta_el).
    Returns False (``out`` untouched) when the elbow is too straight for the rotation to mean anything."""
    best_cost = 1e300
    best_j = 0.0
    best_psi = 0.0
    for sv in (1.0, -1.0):
        b = _mt_v(r_up, v0, v1, sv * v2)
        side = math.hypot(b[0], b[1])
        if side < STRAIGHT_ARM:
            return False
        psi = -s * math.atan2(b[1], b[0])
        inside = min(hi, max(lo, psi))
        cost = abs(psi - inside) + abs(inside)   # beyond the limits counts, then the distance from neutral
        if cost < best_cost:
            best_cost, best_psi, best_j = cost, inside, math.atan2(side, -b[2])
    out[x_psi] = best_psi
    out[xj] = best_j
    return True



@njit(cache=True)
def limb_from_observation(x, data, limb, sign_u, out):
    """``out`` = ``x`` with one limb's three angles solved from its observed 2D landmarks (analytic seed).

    The observed 2D vectors root->middle and middle->end (scaled to metres with the size factor) give the
    segment directions up to the sign of their depth; ``sign_u`` picks the upper segment's, and the lower
    segment's is the one that best lies in the hinge plane -- or, for an arm whose rotation is free, the one
    that needs the rotation nearest neutral, the forearm then exactly on its observation. Segments longer in 2D
    than the model are clipped to the image plane.
    """
    for k in range(x.size):
        out[k] = x[k]
    arm = limb <= LIMB_ARM_R
    k = limb % 2
    s = 1.0 if k == 0 else -1.0
    d = L.D_DIMS
    h = data[d + L.DM_H]
    if arm:
        i0, i1, i2 = L.P_SH_L + k, L.P_EL_L + k, L.P_WR_L + k
        l1, l2 = data[d + L.DM_UA], data[d + L.DM_FA]
        r_root = ROT.mm(ROT.mm(ROT.level_rot(data, L.D_LEVEL), ROT.body_rot(x[L.X_TBD], x[L.X_PBD], x[L.X_SBD])),
                        ROT.mm(ROT.mm(ROT.ry(x[L.X_TTR]), ROT.rx(-x[L.X_PTR])), ROT.rz(x[L.X_STR])))
        xt, xp, xj = (L.X_TSH_L, L.X_PSH_L, L.X_TEL_L) if k == 0 else (L.X_TSH_R, L.X_PSH_R, L.X_TEL_R)
    else:
        i0, i1, i2 = L.P_HP_L + k, L.P_KN_L + k, L.P_AN_L + k
        l1, l2 = data[d + L.DM_TH], data[d + L.DM_SK]
        r_root = ROT.mm(ROT.level_rot(data, L.D_LEVEL), ROT.body_rot(x[L.X_TBD], x[L.X_PBD], x[L.X_SBD]))
        xt, xp, xj = (L.X_THP_L, L.X_PHP_L, L.X_TKN_L) if k == 0 else (L.X_THP_R, L.X_PHP_R, L.X_TKN_R)
    if data[L.D_W + i0] <= 0.0 or data[L.D_W + i1] <= 0.0:
        return
    g = x[L.X_GAMMA]
    o = L.D_OBS
    ux = (data[o + 2 * i1] - data[o + 2 * i0]) * h / g
    uy = (data[o + 2 * i1 + 1] - data[o + 2 * i0 + 1]) * h / g
    q = ux * ux + uy * uy
    if q > l1 * l1:
        f = l1 / math.sqrt(q)
        ux *= f
        uy *= f
        q = l1 * l1
    uz = sign_u * math.sqrt(l1 * l1 - q)
    a = _mt_v(r_root, ux / l1, uy / l1, uz / l1)
    phi = math.asin(min(1.0, max(-1.0, -s * a[1])))
    theta = math.atan2(a[0], -a[2])
    out[xt] = theta
    out[xp] = phi
    if data[L.D_W + i2] <= 0.0:
        return
    vx = (data[o + 2 * i2] - data[o + 2 * i1]) * h / g
    vy = (data[o + 2 * i2 + 1] - data[o + 2 * i1 + 1]) * h / g
    q = vx * vx + vy * vy
    if q > l2 * l2:
        f = l2 / math.sqrt(q)
        vx *= f
        vy *= f
        q = l2 * l2
    vz = math.sqrt(l2 * l2 - q)
    r_up = ROT.mm(ROT.mm(r_root, ROT.ry(-theta)), ROT.rx(-s * phi))
    if arm:
        x_psi = L.X_PSISH_L + k
        lo, hi = data[L.D_LIM_LO + x_psi], data[L.D_LIM_HI + x_psi]
        if hi > lo and _arm_rotation(r_up, vx / l2, vy / l2, vz / l2, s, lo, hi, out, xj, x_psi):
            return
        r_up = ROT.mm(r_up, ROT.rz(-s * x[x_psi]))   # the upper arm's rotation kept: the forearm in its hinge plane
    best_j = 0.0
    best_off = 1e300
    for sv in (1.0, -1.0):
        b = _mt_v(r_up, vx / l2, vy / l2, sv * vz / l2)
        j = math.atan2(b[0], -b[2]) if arm else math.atan2(-b[0], -b[2])
        off = abs(b[1]) + (0.0 if j >= 0.0 else -j)
        if off < best_off:
            best_off = off
            best_j = j
    out[xj] = max(best_j, 0.0)


@njit(cache=True)
def limb_depth_sign(x, data, limb):
    """Sign of the camera depth of the limb's upper segment (root -> middle joint) in the model."""
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, data, pts_b, pts_c)
    k = limb % 2
    if limb <= LIMB_ARM_R:
        dz = pts_c[L.P_EL_L + k, 2] - pts_c[L.P_SH_L + k, 2]
    else:
        dz = pts_c[L.P_KN_L + k, 2] - pts_c[L.P_HP_L + k, 2]
    return 1.0 if dz >= 0.0 else -1.0


@njit(cache=True)
def limb_flip(x, data, limb, out):
    """The limb re-solved from its 2D landmarks with the opposite depth of its upper segment (the mirror
    hypothesis of trap 2), the rest of ``x`` kept."""
    limb_from_observation(x, data, limb, -limb_depth_sign(x, data, limb), out)
