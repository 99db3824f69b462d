"""numba kernels: the least-squares residuals of the refinement and their analytic Jacobian d res / d x.
``cache=True``; tested against central finite differences in ``tests/fitting/test_kinematics.py``.

Residual layout (``R_*`` in fitting.layout, N_RES = 91 rows):

* R_LM + 2 i + c: landmark i, image axis c: sqrt(w_i / sum w) (b_ic - a_ic T_c), b = observed - model
  projection before the translation, a = d(model) / dT (1 orthographic, fn_c / Z'_i perspective), T the
  weighted least-squares translation. The sum of their squares is the weighted mean squared 2D error
  (normalized image units squared).
* R_PEN.., R_LIM.., R_PRIOR.., R_FLEX..: penalty hinges, joint-limit hinges, pose-prior rows and the
  knees' and elbows' measured flexion (:mod:`fitting.penalties`; zero rows without a measurement).
* R_DEPTH + i: landmark i's measured depth, w_i (Z_i - target_i): Z_i its camera-axes depth relative to the
  mid-hip (metres), the target and the weight set per refinement by fitting.depth_term (robust weights,
  re-solved between refinements); zero rows without depth. d Z_i / d x is the point Jacobian's z row.

The landmark Jacobian is built by the chain rule: the camera-axes velocity of each landmark under each
joint angle is a x (p - o) for the joint's rotation axis a (camera axes) through its centre o
(:func:`_point_jacobian`); the projection turns it into image units and the translation's own dependence
on x is differentiated through T = N / D, both in :func:`_landmark_rows`.

:func:`residuals_jacobian` allocates its work arrays; the refinement's inner loop uses the allocation-free
pair :func:`residuals_into` and :func:`jacobian_into` on reused ones (:func:`empty_work`), the Jacobian from
what the residuals left in them at the same x.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.forward_kinematics import empty_work as empty_fk_work
from posed.fitting.forward_kinematics import model_points_into
from posed.fitting.penalties import hinge_jacobian, hinge_residuals
from posed.fitting.projection import MIN_DEPTH, project
from posed.fitting.rotations import column, level_rot, mm, r0, rx, ry, rz

ORIGIN = (0.0, 0.0, 0.0)  # the mid-hip: centre of the body and lumbar rotations


@njit(cache=True)
def n_residuals():
    """Length of the residual vector (N_RES)."""
    return L.N_RES


@njit(cache=True)
def sum_sq(res):
    """Sum of squares of ``res``."""
    acc = 0.0
    for v in res:
        acc += v * v
    return acc


@njit(cache=True)
def _neg(v):
    return (-v[0], -v[1], -v[2])


@njit(cache=True)
def _scaled(s, v):
    return (s * v[0], s * v[1], s * v[2])


@njit(cache=True)
def _point(pts, i):
    return (pts[i, 0], pts[i, 1], pts[i, 2])


@njit(cache=True)
def _rate(jp, i, k, a, p, o):
    """jp[i, :, k] = a x (p - o): the velocity of point p (landmark i) under a unit rate of variable k about
    the axis a through o."""
    vx, vy, vz = p[0] - o[0], p[1] - o[1], p[2] - o[2]
    jp[i, 0, k] = a[1] * vz - a[2] * vy
    jp[i, 1, k] = a[2] * vx - a[0] * vz
    jp[i, 2, k] = a[0] * vy - a[1] * vx


@njit(cache=True)
def _point_jacobian(x, data, pts_c, jp):
    """jp[i] (3 x 21): d (camera-axes position of landmark i) / d x, metres per radian (gamma column 0)."""
    # body R_CB = R_CL R0 Rz(psi_bd) Rx(-phi_bd) Ry(theta_bd): moves every point about the mid-hip
    r_cl0 = mm(level_rot(data, L.D_LEVEL), r0())
    r_bd = mm(r_cl0, mm(mm(rz(x[L.X_SBD]), rx(-x[L.X_PBD])), ry(x[L.X_TBD])))
    r_z = mm(r_cl0, rz(x[L.X_SBD]))
    r_zx = mm(r_z, rx(-x[L.X_PBD]))
    a_psi = column(r_cl0, 2)
    a_phi = _neg(column(r_z, 0))
    a_theta = column(r_zx, 1)
    for i in range(L.N_LM):
        p = _point(pts_c, i)
        _rate(jp, i, L.X_SBD, a_psi, p, ORIGIN)
        _rate(jp, i, L.X_PBD, a_phi, p, ORIGIN)
        _rate(jp, i, L.X_TBD, a_theta, p, ORIGIN)
    # lumbar Ry(theta_tr) Rx(-phi_tr) Rz(psi_tr) about the mid-hip: moves shoulders, elbows and wrists
    r_t = mm(r_bd, ry(x[L.X_TTR]))
    r_tp = mm(r_t, rx(-x[L.X_PTR]))
    a_ttr = column(r_bd, 1)
    a_ptr = _neg(column(r_t, 0))
    a_str = column(r_tp, 2)
    r_tr = mm(r_tp, rz(x[L.X_STR]))  # camera axes of the torso frame
    for i in (L.P_SH_L, L.P_SH_R, L.P_EL_L, L.P_EL_R, L.P_WR_L, L.P_WR_R):
        p = _point(pts_c, i)
        _rate(jp, i, L.X_TTR, a_ttr, p, ORIGIN)
        _rate(jp, i, L.X_PTR, a_ptr, p, ORIGIN)
        _rate(jp, i, L.X_STR, a_str, p, ORIGIN)
    # arm k (s = +1 left, -1 right): shoulder Ry(-theta_sh) Rx(-s phi_sh) Rz(-s psi_sh), elbow Ry(-theta_el)
    for k in range(2):
        s = 1.0 if k == 0 else -1.0
        i_sh, i_el, i_wr = L.P_SH_L + k, L.P_EL_L + k, L.P_WR_L + k
        x_tsh = L.X_TSH_L if k == 0 else L.X_TSH_R
        x_psh = L.X_PSH_L if k == 0 else L.X_PSH_R
        x_psish = L.X_PSISH_L if k == 0 else L.X_PSISH_R
        x_tel = L.X_TEL_L if k == 0 else L.X_TEL_R
        a_tsh = _neg(column(r_tr, 1))
        r_a = mm(r_tr, ry(-x[x_tsh]))
        a_psh = _scaled(-s, column(r_a, 0))
        r_ap = mm(r_a, rx(-s * x[x_psh]))
        a_psish = _scaled(-s, column(r_ap, 2))   # the upper arm's own axis: moves the wrist only
        r_ua = mm(r_ap, rz(-s * x[x_psish]))
        a_tel = _neg(column(r_ua, 1))
        o_sh = _point(pts_c, i_sh)
        for i in (i_el, i_wr):
            p = _point(pts_c, i)
            _rate(jp, i, x_tsh, a_tsh, p, o_sh)
            _rate(jp, i, x_psh, a_psh, p, o_sh)
        _rate(jp, i_wr, x_psish, a_psish, _point(pts_c, i_wr), _point(pts_c, i_el))
        _rate(jp, i_wr, x_tel, a_tel, _point(pts_c, i_wr), _point(pts_c, i_el))
    # leg k: hip Ry(-theta_hp) Rx(-s phi_hp) Rz(-s psi_hp) (psi_hp fixed), knee Ry(theta_kn)
    for k in range(2):
        s = 1.0 if k == 0 else -1.0
        i_hp, i_kn, i_an = L.P_HP_L + k, L.P_KN_L + k, L.P_AN_L + k
        x_thp = L.X_THP_L if k == 0 else L.X_THP_R
        x_php = L.X_PHP_L if k == 0 else L.X_PHP_R
        x_tkn = L.X_TKN_L if k == 0 else L.X_TKN_R
        psi_hp = data[L.D_FIXED + L.F_PSIHP_L] if k == 0 else data[L.D_FIXED + L.F_PSIHP_R]
        a_thp = _neg(column(r_bd, 1))
        r_a = mm(r_bd, ry(-x[x_thp]))
        a_php = _scaled(-s, column(r_a, 0))
        r_th = mm(mm(r_a, rx(-s * x[x_php])), rz(-s * psi_hp))
        a_tkn = column(r_th, 1)
        o_hp = _point(pts_c, i_hp)
        for i in (i_kn, i_an):
            p = _point(pts_c, i)
            _rate(jp, i, x_thp, a_thp, p, o_hp)
            _rate(jp, i, x_php, a_php, p, o_hp)
        _rate(jp, i_an, x_tkn, a_tkn, _point(pts_c, i_an), _point(pts_c, i_kn))


@njit(cache=True)
def _landmark_rows(x, data, pts_c, jp, sw, a_, b_, t_, nn, dd, dq, da, sq, jac):
    """Rows R_LM.. of the Jacobian: d r_ic = -dq_ic - da_ic T_c - a_ic dT_c, T = N / D,
    dT = (dN D - N dD) / D^2. dq_ic and da_ic: the rates of landmark i's model projection on image axis c
    and of its translation coefficient a_ic, from the point Jacobian ``jp`` through the camera model
    (normalized units; da is zero for the orthographic camera, where a = 1), into the work arrays ``dq``,
    ``da`` (2 x 19 x 12); ``sq`` (12): work array for the rows' weights."""
    h = data[L.D_DIMS + L.DM_H]
    g = x[L.X_GAMMA]
    n = L.N_VAR
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        da[:] = 0.0
        gh = g / h
        for i in range(L.N_LM):
            for c in range(2):
                dq[c, L.X_GAMMA, i] = pts_c[i, c] / h
                for k in range(1, n):
                    dq[c, k, i] = gh * jp[i, c, k]
    else:
        tz = data[L.D_PROJ + L.PJ_FN_Y] * h / g
        dtz = -tz / g
        for i in range(L.N_LM):
            z = tz + pts_c[i, 2]
            if z < MIN_DEPTH * tz:
                z = MIN_DEPTH * tz
            iz = 1.0 / z
            iz2 = iz * iz
            for c in range(2):
                fn = data[L.D_PROJ + L.PJ_FN_X + c]
                pc = pts_c[i, c]
                dq[c, L.X_GAMMA, i] = -fn * pc * dtz * iz2
                da[c, L.X_GAMMA, i] = -fn * dtz * iz2
                for k in range(1, n):
                    dq[c, k, i] = fn * (jp[i, c, k] * iz - pc * jp[i, 2, k] * iz2)
                    da[c, k, i] = -fn * jp[i, 2, k] * iz2
    for i in range(L.N_LM):
        sq[i] = math.sqrt(data[L.D_W + i] / sw)
    for c in range(2):
        for k in range(n):
            dn = 0.0
            d_d = 0.0
            for i in range(L.N_LM):
                w = data[L.D_W + i]
                dn += w * (da[c, k, i] * b_[i, c] - a_[i, c] * dq[c, k, i])
                d_d += 2.0 * w * a_[i, c] * da[c, k, i]
            dt = (dn * dd[c] - nn[c] * d_d) / (dd[c] * dd[c]) if dd[c] > 0.0 else 0.0
            for i in range(L.N_LM):
                jac[L.R_LM + 2 * i + c, k] = sq[i] * (-dq[c, k, i] - da[c, k, i] * t_[c] - a_[i, c] * dt)


@njit(cache=True)
def empty_work():
    """Work arrays of :func:`residuals_into` and :func:`jacobian_into`, reusable from call to call: the tuple
    (pts_b, pts_c (19 x 3), forward-kinematics work (fitting.forward_kinematics.empty_work), proj (12 x 3),
    a_, b_ (12 x 2), tnd (3 x 2: the translation T, N and D per image axis), jp (12 x 3 x 19, zero where no
    joint moves the landmark), dq, da (2 x 19 x 12), sq (12))."""
    return (np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3)), empty_fk_work(), np.empty((L.N_LM, 3)),
            np.empty((L.N_LM, 2)), np.empty((L.N_LM, 2)), np.empty((3, 2)), np.zeros((L.N_LM, 3, L.N_VAR)),
            np.empty((2, L.N_VAR, L.N_LM)), np.empty((2, L.N_VAR, L.N_LM)), np.empty(L.N_LM))


@njit(cache=True)
def _weight_sum(data):
    """sum_i w_i of the landmark weights (1 when there is none)."""
    sw = 0.0
    for i in range(L.N_LM):
        sw += data[L.D_W + i]
    return 1.0 if sw <= 0.0 else sw


@njit(cache=True)
def residuals_jacobian(x, data, res, jac, want_jac):
    """Least-squares residuals (layout R_*, see the module docstring) into ``res`` (N_RES) and, when
    ``want_jac``, their Jacobian d res / d x into ``jac`` (N_RES x N_VAR)."""
    work = empty_work()
    residuals_into(x, data, res, work)
    if want_jac:
        jacobian_into(x, data, jac, work)


@njit(cache=True)
def residuals_into(x, data, res, work):
    """The residuals of :func:`residuals_jacobian` into ``res`` with the work arrays of :func:`empty_work`,
    which keep what :func:`jacobian_into` needs at the same ``x``."""
    pts_b, pts_c, fk, proj, a_, b_, tnd, _, _, _, _ = work
    t_, nn, dd = tnd[0], tnd[1], tnd[2]  # N_c = sum_i w_i a_ic b_ic, D_c = sum_i w_i a_ic^2
    model_points_into(x, data, pts_b, pts_c, fk)
    project(x, pts_c, data, proj)
    persp = data[L.D_PROJ + L.PJ_MODE] != L.PROJ_ORTHOGRAPHIC
    sw = _weight_sum(data)
    # r_ic = b_ic - a_ic T_c, b = observed - model (no translation), a = d(model) / dT
    for c in range(2):
        nn[c] = 0.0
        dd[c] = 0.0
    for i in range(L.N_LM):
        w = data[L.D_W + i]
        for c in range(2):
            if persp:
                a_[i, c] = data[L.D_PROJ + L.PJ_FN_X + c] * proj[i, 2]
                b_[i, c] = data[L.D_OBS + 2 * i + c] + data[L.D_PROJ + L.PJ_OFF_X + c] - proj[i, c]
            else:
                a_[i, c] = 1.0
                b_[i, c] = data[L.D_OBS + 2 * i + c] - proj[i, c]
            nn[c] += w * a_[i, c] * b_[i, c]
            dd[c] += w * a_[i, c] * a_[i, c]
    for c in range(2):
        t_[c] = nn[c] / dd[c] if dd[c] > 0.0 else 0.0
    for i in range(L.N_LM):
        sq = math.sqrt(data[L.D_W + i] / sw)
        res[L.R_LM + 2 * i] = sq * (b_[i, 0] - a_[i, 0] * t_[0])
        res[L.R_LM + 2 * i + 1] = sq * (b_[i, 1] - a_[i, 1] * t_[1])
    hinge_residuals(x, data, res)
    for i in range(L.N_LM):
        res[L.R_DEPTH + i] = data[L.D_DEPTH_W + i] * (pts_c[i, 2] - data[L.D_DEPTH + i])


@njit(cache=True)
def jacobian_into(x, data, jac, work):
    """The Jacobian of :func:`residuals_jacobian` into ``jac``, from the work arrays that
    :func:`residuals_into` filled at the same ``x`` (no allocation)."""
    _, pts_c, _, _, a_, b_, tnd, jp, dq, da, sq = work
    _point_jacobian(x, data, pts_c, jp)
    _landmark_rows(x, data, pts_c, jp, _weight_sum(data), a_, b_, tnd[0], tnd[1], tnd[2], dq, da, sq, jac)
    hinge_jacobian(x, data, jac)
    for i in range(L.N_LM):
        wd = data[L.D_DEPTH_W + i]
        for k in range(L.N_VAR):
            jac[L.R_DEPTH + i, k] = wd * jp[i, 2, k]
