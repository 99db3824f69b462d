"""numba kernels of the fit: forward kinematics, the loss of the paper's section 4.2 and the least-squares
residuals with their analytic Jacobian. Pure functions of their arrays, ``cache=True``; the forward
kinematics is tested against the NumPy reference in :mod:`fitting.kinematics`, the loss terms against the
NumPy references in ``tests/fitting/test_loss.py`` and the Jacobian against finite differences.

Vector layouts (all angles radians inside the kernels):

* ``x`` (19): the paper's eq. (6) order, see ``fitting.result.VARIABLE_NAMES``; x[0] is the size factor
  relative to the reference scale of the frame (1 = the scale estimated from the landmarks).
* ``fixed`` (8): joint angles that are not optimized: theta_hd, psi_hd, psi_hp_l, psi_hp_r, theta_an_l,
  phi_an_l, theta_an_r, phi_an_r.
* ``dims`` (11): ``fitting.body.BodyDimensions`` in field order (metres).
* ``data``: everything one frame's loss needs, packed at the ``D_*`` offsets below (built by
  :func:`fitting.problem.pack`).
* model points (19 x 3): P_* indices below; pelvis frame or camera axes, metres, origin at the mid-hip.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from fitting import jitcache

jitcache.ensure_fresh()  # before any kernel is loaded from numba's cache

# --- variable indices (eq. 6) ---
X_GAMMA, X_TBD, X_PBD, X_SBD, X_TTR, X_PTR, X_STR = 0, 1, 2, 3, 4, 5, 6
X_THP_L, X_TKN_L, X_THP_R, X_TKN_R = 7, 8, 9, 10
X_TSH_L, X_TEL_L, X_TSH_R, X_TEL_R = 11, 12, 13, 14
X_PHP_L, X_PHP_R, X_PSH_L, X_PSH_R = 15, 16, 17, 18
N_VAR = 19

# --- fixed joint angles ---
F_THD, F_PHD, F_PSIHP_L, F_PSIHP_R, F_TAN_L, F_PAN_L, F_TAN_R, F_PAN_R = 0, 1, 2, 3, 4, 5, 6, 7
N_FIXED = 8

# --- dims ---
DM_H, DM_TRUNK, DM_SH, DM_HP, DM_UA, DM_FA, DM_HAND, DM_TH, DM_SK, DM_ANK, DM_FOOT = range(11)
N_DIMS = 11

# --- model points: the 12 body landmarks in BODY_LANDMARKS order, then the rest ---
P_SH_L, P_SH_R, P_EL_L, P_EL_R, P_WR_L, P_WR_R = 0, 1, 2, 3, 4, 5
P_HP_L, P_HP_R, P_KN_L, P_KN_R, P_AN_L, P_AN_R = 6, 7, 8, 9, 10, 11
P_HEEL_L, P_HEEL_R, P_TOE_L, P_TOE_R, P_HEAD, P_MIDSH, P_COM = 12, 13, 14, 15, 16, 17, 18
N_POINTS = 19
N_LM = 12

# --- data layout ---
D_OBS = 0             # 24: observed landmarks, normalized image units (x, y) per landmark
D_W = 24              # 12: landmark weights (0 = not used)
D_DIMS = 36           # 11
D_FIXED = 47          # 8
D_PROJ = 55           # 5: mode (0 orthographic, 1 perspective), fn_x, fn_y, ray_x, ray_y of the mid-hip
D_LW = 60             # loss weights, see LW_*
LW_COM, LW_SYM, LW_SAG_TR, LW_COR_TR, LW_TRAN_TR, LW_SAG_SH, LW_COR_SH = 0, 1, 2, 3, 4, 5, 6
LW_NULL, LW_PRIOR_TR, LW_PRIOR_HP, LW_PRIOR_UP, LW_COM_MODE, LW_CONTACT, LW_MARGIN, LW_SEAT = 7, 8, 9, 10, 11, 12, 13, 14
LW_LIMIT = 15         # weight of the joint-limit hinge (refinement only)
LW_COR_HP = 16        # weight of P_sp(phi_hp, hp adduction max) [beyond the paper]
N_LW = 17
N_TH = 6
D_TH = D_LW + N_LW    # thresholds (rad): tr flexion min, tr lateral +-, tr twist +-, sh flexion min,
                      # sh adduction max, hp adduction max
D_LIM_LO = D_TH + N_TH            # 19 joint limits (refinement hinge)
D_LIM_HI = D_LIM_LO + N_VAR       # 19
D_PRIOR = D_LIM_HI + N_VAR        # 1: weight lambda of the pose prior (refinement only; 0 = off)
D_PRIOR_MU = D_PRIOR + 1          # 19: prior means (kernel units)
D_PRIOR_SIG = D_PRIOR_MU + N_VAR  # 19: prior standard deviations (<= 0: no prior on that variable)
D_PRIOR_PARTNER = D_PRIOR_SIG + N_VAR  # 19: partner variable (prior on x_k - x_partner), -1 for none
D_SIZE = D_PRIOR_PARTNER + N_VAR

COM_FEET, COM_SUPPORT = 0, 1

# Dempster / Winter segment masses (fitting.body.SEGMENT_MASS) and centre-of-mass fractions.
M_TRUNK, M_HEAD, M_UA, M_FA, M_HAND, M_TH, M_SK, M_FOOT = 0.497, 0.081, 0.028, 0.016, 0.006, 0.100, 0.0465, 0.0145
C_UA, C_FA, C_HAND, C_TH, C_SK = 0.436, 0.430, 0.506, 0.433, 0.433
HEAD_EAR_HEIGHT = 0.112  # ear midpoint above the mid-shoulder, fraction of body height (fitting.kinematics)


# --- 3x3 rotations as row-major 9-tuples (no allocation in the hot loop) ---

@njit(cache=True)
def mm(a, b):
    return (a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
            a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
            a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8])


@njit(cache=True)
def rx(a):
    c, s = math.cos(a), math.sin(a)
    return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)


@njit(cache=True)
def ry(a):
    c, s = math.cos(a), math.sin(a)
    return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)


@njit(cache=True)
def rz(a):
    c, s = math.cos(a), math.sin(a)
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


@njit(cache=True)
def r0():
    """Camera axes of the pelvis axes in the neutral pose (fitting.kinematics.R0)."""
    return (0.0, 1.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 0.0)


@njit(cache=True)
def body_rot(theta, phi, psi):
    """R_CB = R0 Rz(psi) Rx(-phi) Ry(theta)."""
    return mm(mm(mm(r0(), rz(psi)), rx(-phi)), ry(theta))


@njit(cache=True)
def _put(out, i, ox, oy, oz, r, vx, vy, vz):
    """out[i] = o + r v."""
    out[i, 0] = ox + r[0] * vx + r[1] * vy + r[2] * vz
    out[i, 1] = oy + r[3] * vx + r[4] * vy + r[5] * vz
    out[i, 2] = oz + r[6] * vx + r[7] * vy + r[8] * vz


N_SLOTS = N_VAR + N_FIXED  # angle slots of the trig table: the 19 variables (slot 0 unused), then fixed

# Work array of the loss: one (W_ROWS, 3) float64 array, no views in the hot path.
W_PTS_B = 0                   # 19 rows: model points in the pelvis frame
W_PTS_C = W_PTS_B + N_POINTS  # 19 rows: in camera axes
W_PROJ = W_PTS_C + N_POINTS   # 12 rows: normalized image coordinates (columns 0, 1)
W_TRIG = W_PROJ + N_LM        # 27 rows: (angle, cos, sin) per slot, recomputed only when the angle changes
W_RTR = W_TRIG + N_SLOTS      # 3 rows: torso rotation (pelvis from torso), row-major
W_RBD = W_RTR + 3             # 3 rows: body rotation R_CB
W_SIG = W_RBD + 3             # 1 row: signature of the dims the cached points were computed with
W_ROWS = W_SIG + 1

# groups of angle slots whose change moves the same points (bit masks)
G_BODY, G_TORSO, G_ARM_L, G_ARM_R, G_LEG_L, G_LEG_R = 1, 2, 4, 8, 16, 32
G_ALL = 63


@njit(cache=True)
def _slot_group(k):
    if k == X_TBD or k == X_PBD or k == X_SBD:
        return G_BODY
    if k == X_TTR or k == X_PTR or k == X_STR or k == N_VAR + F_THD or k == N_VAR + F_PHD:
        return G_TORSO
    if k == X_TSH_L or k == X_TEL_L or k == X_PSH_L:
        return G_ARM_L
    if k == X_TSH_R or k == X_TEL_R or k == X_PSH_R:
        return G_ARM_R
    if k == X_THP_L or k == X_TKN_L or k == X_PHP_L or k == N_VAR + F_PSIHP_L or k == N_VAR + F_TAN_L \
            or k == N_VAR + F_PAN_L:
        return G_LEG_L
    if k == X_THP_R or k == X_TKN_R or k == X_PHP_R or k == N_VAR + F_PSIHP_R or k == N_VAR + F_TAN_R \
            or k == N_VAR + F_PAN_R:
        return G_LEG_R
    return 0


@njit(cache=True)
def rx_cs(c, s):
    return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)


@njit(cache=True)
def ry_cs(c, s):
    return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)


@njit(cache=True)
def rz_cs(c, s):
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


@njit(cache=True)
def update_trig(x, data, work):
    """Refresh the trig table for the angles that changed since the last call (uDEAS moves one at a time);
    returns the bit mask of the point groups that moved (G_ALL when the body dimensions changed)."""
    mask = 0
    sig = 0.0
    for k in range(N_DIMS):
        sig += data[D_DIMS + k] * (k + 1)
    if work[W_SIG, 0] != sig:
        work[W_SIG, 0] = sig
        mask = G_ALL
    for k in range(1, N_VAR):
        r = W_TRIG + k
        if work[r, 0] != x[k]:
            work[r, 0] = x[k]
            work[r, 1] = math.cos(x[k])
            work[r, 2] = math.sin(x[k])
            mask |= _slot_group(k)
    for k in range(N_FIXED):
        r = W_TRIG + N_VAR + k
        a = data[D_FIXED + k]
        if work[r, 0] != a:
            work[r, 0] = a
            work[r, 1] = math.cos(a)
            work[r, 2] = math.sin(a)
            mask |= _slot_group(N_VAR + k)
    return mask


@njit(cache=True)
def _ry(work, k, sign):
    r = W_TRIG + k
    return ry_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def _rx(work, k, sign):
    r = W_TRIG + k
    return rx_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def _rz(work, k, sign):
    r = W_TRIG + k
    return rz_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def _store_rot(work, row, r):
    for i in range(3):
        for j in range(3):
            work[row + i, j] = r[3 * i + j]


@njit(cache=True)
def _load_rot(work, row):
    return (work[row, 0], work[row, 1], work[row, 2], work[row + 1, 0], work[row + 1, 1], work[row + 1, 2],
            work[row + 2, 0], work[row + 2, 1], work[row + 2, 2])


@njit(cache=True)
def body_rot_w(work):
    """R_CB = R0 Rz(psi) Rx(-phi) Ry(theta) from the trig table."""
    return mm(mm(mm(r0(), _rz(work, X_SBD, 1.0)), _rx(work, X_PBD, -1.0)), _ry(work, X_TBD, 1.0))


@njit(cache=True)
def torso_rot_w(work):
    """Pelvis from torso: Ry(theta_tr) Rx(-phi_tr) Rz(psi_tr)."""
    return mm(mm(_ry(work, X_TTR, 1.0), _rx(work, X_PTR, -1.0)), _rz(work, X_STR, 1.0))


@njit(cache=True)
def _fk_torso(data, work):
    d = D_DIMS
    b = W_PTS_B
    lt = data[d + DM_TRUNK]
    r_tr = torso_rot_w(work)
    _store_rot(work, W_RTR, r_tr)
    _put(work, b + P_MIDSH, 0.0, 0.0, 0.0, r_tr, 0.0, 0.0, lt)
    fh = N_VAR
    r_hd = mm(mm(r_tr, _ry(work, fh + F_THD, 1.0)), _rz(work, fh + F_PHD, 1.0))
    m = b + P_MIDSH
    _put(work, b + P_HEAD, work[m, 0], work[m, 1], work[m, 2], r_hd, 0.0, 0.0, HEAD_EAR_HEIGHT * data[d + DM_H])
    _put(work, b + P_SH_L, 0.0, 0.0, 0.0, r_tr, 0.0, data[d + DM_SH], lt)
    _put(work, b + P_SH_R, 0.0, 0.0, 0.0, r_tr, 0.0, -data[d + DM_SH], lt)


@njit(cache=True)
def _fk_arm(k, data, work):
    d = D_DIMS
    b = W_PTS_B
    s = 1.0 if k == 0 else -1.0
    ish, iel, iwr = b + P_SH_L + k, b + P_EL_L + k, b + P_WR_L + k
    kt = X_TSH_L if k == 0 else X_TSH_R
    kp = X_PSH_L if k == 0 else X_PSH_R
    ke = X_TEL_L if k == 0 else X_TEL_R
    r_tr = _load_rot(work, W_RTR)
    r_ua = mm(mm(r_tr, _ry(work, kt, -1.0)), _rx(work, kp, -s))
    _put(work, iel, work[ish, 0], work[ish, 1], work[ish, 2], r_ua, 0.0, 0.0, -data[d + DM_UA])
    r_fa = mm(r_ua, _ry(work, ke, -1.0))
    _put(work, iwr, work[iel, 0], work[iel, 1], work[iel, 2], r_fa, 0.0, 0.0, -data[d + DM_FA])


@njit(cache=True)
def _fk_leg(k, data, work):
    d = D_DIMS
    b = W_PTS_B
    fh = N_VAR
    s = 1.0 if k == 0 else -1.0
    ihp, ikn, ian = b + P_HP_L + k, b + P_KN_L + k, b + P_AN_L + k
    ihe, ito = b + P_HEEL_L + k, b + P_TOE_L + k
    kt = X_THP_L if k == 0 else X_THP_R
    kp = X_PHP_L if k == 0 else X_PHP_R
    kk = X_TKN_L if k == 0 else X_TKN_R
    kps = fh + (F_PSIHP_L if k == 0 else F_PSIHP_R)
    kat = fh + (F_TAN_L if k == 0 else F_TAN_R)
    kap = fh + (F_PAN_L if k == 0 else F_PAN_R)
    work[ihp, 0] = 0.0
    work[ihp, 1] = s * data[d + DM_HP]
    work[ihp, 2] = 0.0
    r_th = mm(mm(_ry(work, kt, -1.0), _rx(work, kp, -s)), _rz(work, kps, -s))
    _put(work, ikn, work[ihp, 0], work[ihp, 1], work[ihp, 2], r_th, 0.0, 0.0, -data[d + DM_TH])
    r_sk = mm(r_th, _ry(work, kk, 1.0))
    _put(work, ian, work[ikn, 0], work[ikn, 1], work[ikn, 2], r_sk, 0.0, 0.0, -data[d + DM_SK])
    r_ft = mm(mm(r_sk, _ry(work, kat, -1.0)), _rx(work, kap, -s))
    fl, ah = data[d + DM_FOOT], data[d + DM_ANK]
    _put(work, ihe, work[ian, 0], work[ian, 1], work[ian, 2], r_ft, -0.25 * fl, 0.0, -ah)
    _put(work, ito, work[ian, 0], work[ian, 1], work[ian, 2], r_ft, 0.75 * fl, 0.0, -ah)


@njit(cache=True)
def _com(data, work):
    """Whole-body centre of mass from the pelvis-frame points (Dempster fractions)."""
    d = D_DIMS
    b = W_PTS_B
    hand = C_HAND * 0.5 * data[d + DM_HAND] / data[d + DM_FA]
    for c in range(3):
        acc = M_TRUNK * 0.5 * work[b + P_MIDSH, c] + M_HEAD * work[b + P_HEAD, c]
        for k in range(2):
            sh, el, wr = work[b + P_SH_L + k, c], work[b + P_EL_L + k, c], work[b + P_WR_L + k, c]
            acc += M_UA * (sh + C_UA * (el - sh)) + M_FA * (el + C_FA * (wr - el)) + M_HAND * (wr + hand * (wr - el))
            hp, kn, an = work[b + P_HP_L + k, c], work[b + P_KN_L + k, c], work[b + P_AN_L + k, c]
            acc += M_TH * (hp + C_TH * (kn - hp)) + M_SK * (kn + C_SK * (an - kn))
            # ankle + R_ft (0.225 l_foot, 0, -0.5 h_ankle) = 0.5 ankle + 0.15 heel + 0.35 toe
            acc += M_FOOT * (0.5 * an + 0.15 * work[b + P_HEEL_L + k, c] + 0.35 * work[b + P_TOE_L + k, c])
        work[b + P_COM, c] = acc


@njit(cache=True)
def _rotate_rows(work, r_bd, i0, i1):
    for i in range(i0, i1):
        b = W_PTS_B + i
        _put(work, W_PTS_C + i, 0.0, 0.0, 0.0, r_bd, work[b, 0], work[b, 1], work[b, 2])


@njit(cache=True)
def fk_update(mask, data, work):
    """Recompute the pelvis-frame and camera-axes points of the groups in ``mask`` (see update_trig)."""
    if mask & G_TORSO:
        _fk_torso(data, work)
        mask |= G_ARM_L | G_ARM_R
    if mask & G_ARM_L:
        _fk_arm(0, data, work)
    if mask & G_ARM_R:
        _fk_arm(1, data, work)
    if mask & G_LEG_L:
        _fk_leg(0, data, work)
    if mask & G_LEG_R:
        _fk_leg(1, data, work)
    if mask & ~G_BODY:
        _com(data, work)
    if mask & G_BODY:
        _store_rot(work, W_RBD, body_rot_w(work))
    r_bd = _load_rot(work, W_RBD)
    if mask & G_BODY:
        _rotate_rows(work, r_bd, 0, N_POINTS)
        return
    if mask & G_TORSO:
        _rotate_rows(work, r_bd, P_SH_L, P_SH_R + 1)
        _rotate_rows(work, r_bd, P_HEAD, P_MIDSH + 1)
    if mask & G_ARM_L:
        _rotate_rows(work, r_bd, P_EL_L, P_EL_L + 1)
        _rotate_rows(work, r_bd, P_WR_L, P_WR_L + 1)
    if mask & G_ARM_R:
        _rotate_rows(work, r_bd, P_EL_R, P_EL_R + 1)
        _rotate_rows(work, r_bd, P_WR_R, P_WR_R + 1)
    if mask & G_LEG_L:
        for i in (P_HP_L, P_KN_L, P_AN_L, P_HEEL_L, P_TOE_L):
            _rotate_rows(work, r_bd, i, i + 1)
    if mask & G_LEG_R:
        for i in (P_HP_R, P_KN_R, P_AN_R, P_HEEL_R, P_TOE_R):
            _rotate_rows(work, r_bd, i, i + 1)
    if mask:
        _rotate_rows(work, r_bd, P_COM, P_COM + 1)


@njit(cache=True)
def fk_work(data, work):
    """All model points (rows W_PTS_B.., pelvis frame, metres; the centre of mass in row P_COM) from the
    trig table. Returns the torso rotation."""
    _fk_torso(data, work)
    _fk_arm(0, data, work)
    _fk_arm(1, data, work)
    _fk_leg(0, data, work)
    _fk_leg(1, data, work)
    _com(data, work)
    return _load_rot(work, W_RTR)


@njit(cache=True)
def model_points(x, data, pts_b, pts_c):
    """Model points of ``x`` in the pelvis frame and in camera axes (19 x 3 each, metres)."""
    work = np.zeros((W_ROWS, 3))
    for r in range(W_TRIG, W_ROWS):
        work[r, 0] = np.nan
    update_trig(x, data, work)
    fk_work(data, work)
    r_bd = body_rot_w(work)
    for i in range(N_POINTS):
        for c in range(3):
            pts_b[i, c] = work[W_PTS_B + i, c]
        _put(pts_c, i, 0.0, 0.0, 0.0, r_bd, work[W_PTS_B + i, 0], work[W_PTS_B + i, 1], work[W_PTS_B + i, 2])


@njit(cache=True)
def project(x, pts_c, data, out2):
    """Model image coordinates of the 12 landmarks before the translation, normalized units: out2 (12 x 3).

    Orthographic: (g X / H, g Y / H, unused). Perspective (pinhole, camera-centred normalized units): the
    mid-hip sits at depth Tz = fn_y H / g in front of the camera, out2 = (fn_x X / Z', fn_y Y / Z', 1 / Z')
    with Z' = Tz + Z; the lateral translation (Tx, Ty) is solved by weighted least squares in
    :func:`mpjpe` / :func:`residuals_jacobian` (exact: the residual is linear in it).
    """
    h = data[D_DIMS + DM_H]
    g = x[X_GAMMA]
    if data[D_PROJ] == 0.0:
        for i in range(N_LM):
            out2[i, 0] = g * pts_c[i, 0] / h
            out2[i, 1] = g * pts_c[i, 1] / h
            out2[i, 2] = 0.0
    else:
        fnx, fny = data[D_PROJ + 1], data[D_PROJ + 2]
        tz = fny * h / g
        for i in range(N_LM):
            zz = tz + pts_c[i, 2]
            if zz < 1e-3 * tz:
                zz = 1e-3 * tz
            out2[i, 0] = fnx * pts_c[i, 0] / zz
            out2[i, 1] = fny * pts_c[i, 1] / zz
            out2[i, 2] = 1.0 / zz


@njit(cache=True)
def project_w(x, data, work):
    """project() on the work rows: W_PTS_C -> W_PROJ."""
    h = data[D_DIMS + DM_H]
    g = x[X_GAMMA]
    c0 = W_PTS_C
    p0 = W_PROJ
    if data[D_PROJ] == 0.0:
        k = g / h
        for i in range(N_LM):
            work[p0 + i, 0] = k * work[c0 + i, 0]
            work[p0 + i, 1] = k * work[c0 + i, 1]
    else:
        fnx, fny = data[D_PROJ + 1], data[D_PROJ + 2]
        tz = fny * h / g
        for i in range(N_LM):
            zz = tz + work[c0 + i, 2]
            if zz < 1e-3 * tz:
                zz = 1e-3 * tz
            inv = 1.0 / zz
            work[p0 + i, 0] = fnx * work[c0 + i, 0] * inv
            work[p0 + i, 1] = fny * work[c0 + i, 1] * inv
            work[p0 + i, 2] = inv


# --- loss terms ---

@njit(cache=True)
def p_sn(a, sigma):
    """Single-sided negative penalty, eq. (9)."""
    return sigma - a if a < sigma else 0.0


@njit(cache=True)
def p_sp(a, sigma):
    """Single-sided positive penalty, eq. (10)."""
    return a - sigma if a > sigma else 0.0


@njit(cache=True)
def p_d(a, lo, hi):
    """Double-sided penalty, eq. (11)."""
    if a < lo:
        return lo - a
    if a >= hi:
        return a - hi
    return 0.0


@njit(cache=True)
def mpjpe(proj, r0, data):
    """Eq. (7): weighted mean 2D distance after the best translation (normalized units).

    ``proj[r0 + i]`` holds landmark i's model projection from :func:`project`. Orthographic: the best
    translation aligns the weighted centroids. Perspective: the lateral translation of the body enters
    as a_i T with a_i = fn / Z'_i; its weighted least-squares value is used.
    """
    sw = 0.0
    for i in range(N_LM):
        sw += data[D_W + i]
    if sw <= 0.0:
        return 0.0
    acc = 0.0
    if data[D_PROJ] == 0.0:
        tx = 0.0
        ty = 0.0
        for i in range(N_LM):
            w = data[D_W + i]
            tx += w * (data[D_OBS + 2 * i] - proj[r0 + i, 0])
            ty += w * (data[D_OBS + 2 * i + 1] - proj[r0 + i, 1])
        tx /= sw
        ty /= sw
        for i in range(N_LM):
            w = data[D_W + i]
            if w > 0.0:
                dx = data[D_OBS + 2 * i] - proj[r0 + i, 0] - tx
                dy = data[D_OBS + 2 * i + 1] - proj[r0 + i, 1] - ty
                acc += w * math.sqrt(dx * dx + dy * dy)
        return acc / sw
    fnx, fny, offx, offy = data[D_PROJ + 1], data[D_PROJ + 2], data[D_PROJ + 3], data[D_PROJ + 4]
    nx = 0.0
    dx_ = 0.0
    ny = 0.0
    dy_ = 0.0
    for i in range(N_LM):
        w = data[D_W + i]
        inv = proj[r0 + i, 2]
        ax = fnx * inv
        ay = fny * inv
        bx = data[D_OBS + 2 * i] + offx - proj[r0 + i, 0]
        by = data[D_OBS + 2 * i + 1] + offy - proj[r0 + i, 1]
        nx += w * ax * bx
        dx_ += w * ax * ax
        ny += w * ay * by
        dy_ += w * ay * ay
    tx = nx / dx_
    ty = ny / dy_
    for i in range(N_LM):
        w = data[D_W + i]
        if w > 0.0:
            inv = proj[r0 + i, 2]
            ex = data[D_OBS + 2 * i] + offx - proj[r0 + i, 0] - fnx * inv * tx
            ey = data[D_OBS + 2 * i + 1] + offy - proj[r0 + i, 1] - fny * inv * ty
            acc += w * math.sqrt(ex * ex + ey * ey)
    return acc / sw


SUPPORT_CANDIDATES = (P_HEEL_L, P_HEEL_R, P_TOE_L, P_TOE_R, P_KN_L, P_KN_R, P_HP_L, P_HP_R, P_WR_L, P_WR_R,
                      P_EL_L, P_EL_R, P_SH_L, P_SH_R, P_HEAD)


@njit(cache=True)
def com_deviation(pts_c, r0, data):
    """CoM deviation (the paper's missing eq. 8), normalized by the leg length l_leg.

    ``pts_c[r0 + P_*]``: model points in camera axes. The camera is level: gravity is +y, the floor is
    the x-z plane. ``feet`` mode (paper): the distance on the floor from the CoM to the centre of the
    supporting feet (heel and toe points within ``contact`` of the lowest foot point). ``support`` mode:
    every body point within ``contact`` of the lowest one supports (feet, knees, hips, hands, elbows,
    shoulders, head; the hips also when they are not above their knees: a seat); the deviation is the
    distance of the CoM from the centre of the support points' bounding box (x-z) beyond ``margin`` times
    half its diagonal (zero for a stable pose).
    """
    dm = D_DIMS
    leg = data[dm + DM_TH] + data[dm + DM_SK] + data[dm + DM_ANK]
    contact = data[D_LW + LW_CONTACT] * data[dm + DM_H]
    if data[D_LW + LW_COM_MODE] == COM_FEET:
        ymax = -1e300
        for i in range(P_HEEL_L, P_TOE_R + 1):
            if pts_c[r0 + i, 1] > ymax:
                ymax = pts_c[r0 + i, 1]
        sx = 0.0
        sz = 0.0
        n = 0
        for i in range(P_HEEL_L, P_TOE_R + 1):
            if pts_c[r0 + i, 1] >= ymax - contact:
                sx += pts_c[r0 + i, 0]
                sz += pts_c[r0 + i, 2]
                n += 1
        dx = pts_c[r0 + P_COM, 0] - sx / n
        dz = pts_c[r0 + P_COM, 2] - sz / n
        return math.sqrt(dx * dx + dz * dz) / leg
    ymax = -1e300
    for i in SUPPORT_CANDIDATES:
        y = pts_c[r0 + i, 1]
        if y > ymax:
            ymax = y
    floor = ymax - contact
    seat = data[D_LW + LW_SEAT] > 0.0
    seat_l = seat and pts_c[r0 + P_HP_L, 1] >= pts_c[r0 + P_KN_L, 1] - contact
    seat_r = seat and pts_c[r0 + P_HP_R, 1] >= pts_c[r0 + P_KN_R, 1] - contact
    x0 = 1e300
    x1 = -1e300
    z0 = 1e300
    z1 = -1e300
    for i in SUPPORT_CANDIDATES:
        if pts_c[r0 + i, 1] >= floor or (i == P_HP_L and seat_l) or (i == P_HP_R and seat_r):
            px = pts_c[r0 + i, 0]
            pz = pts_c[r0 + i, 2]
            x0 = min(x0, px)
            x1 = max(x1, px)
            z0 = min(z0, pz)
            z1 = max(z1, pz)
    dx = pts_c[r0 + P_COM, 0] - 0.5 * (x0 + x1)
    dz = pts_c[r0 + P_COM, 2] - 0.5 * (z0 + z1)
    half = 0.5 * math.sqrt((x1 - x0) ** 2 + (z1 - z0) ** 2)
    dev = math.sqrt(dx * dx + dz * dz) - data[D_LW + LW_MARGIN] * half
    return dev / leg if dev > 0.0 else 0.0


@njit(cache=True)
def torso_uprightness(x):
    """cos of the torso's inclination from vertical, clipped at 0 (1 upright, 0 horizontal or below)."""
    r = mm(body_rot(x[X_TBD], x[X_PBD], x[X_SBD]), mm(mm(ry(x[X_TTR]), rx(-x[X_PTR])), rz(x[X_STR])))
    c = -r[5]
    return c if c > 0.0 else 0.0


@njit(cache=True)
def penalties(x, data):
    """Weighted sum of the paper's penalty terms (section 4.2), angles in radians."""
    lw = D_LW
    th = D_TH
    acc = data[lw + LW_SAG_TR] * p_sn(x[X_TTR], data[th])
    acc += data[lw + LW_COR_TR] * p_d(x[X_PTR], -data[th + 1], data[th + 1])
    acc += data[lw + LW_TRAN_TR] * p_d(x[X_STR], -data[th + 2], data[th + 2])
    acc += data[lw + LW_SAG_SH] * (p_sn(x[X_TSH_L], data[th + 3]) + p_sn(x[X_TSH_R], data[th + 3]))
    acc += data[lw + LW_COR_SH] * (p_sp(x[X_PSH_L], data[th + 4]) + p_sp(x[X_PSH_R], data[th + 4]))
    acc += data[lw + LW_COR_HP] * (p_sp(x[X_PHP_L], data[th + 5]) + p_sp(x[X_PHP_R], data[th + 5]))
    return acc


@njit(cache=True)
def pose_loss_terms(x, data, work):
    """Loss of section 4.2 and its terms: (total, mpjpe, comd, sym, penalties, null prior).

    ``work``: a (W_ROWS, 3) array from :func:`empty_work`, reused between calls (its trig table is a cache).
    """
    mask = update_trig(x, data, work)
    fk_update(mask, data, work)
    r_tr = _load_rot(work, W_RTR)
    r_bd = _load_rot(work, W_RBD)
    project_w(x, data, work)
    lw = D_LW
    t_mp = mpjpe(work, W_PROJ, data)
    t_com = com_deviation(work, W_PTS_C, data) if data[lw + LW_COM] > 0.0 else 0.0
    t_sym = abs(x[X_THP_L] - x[X_THP_R]) + abs(x[X_TKN_L] - x[X_TKN_R])
    t_pen = penalties(x, data)
    t_null = 0.0
    if data[lw + LW_NULL] > 0.0:
        # pelvis tilt from vertical: cos = (pelvis up) . (world up) = -R_CB[1, 2]
        c = min(max(-r_bd[5], -1.0), 1.0)
        # torso uprightness: -(R_CB R_tr)[1, 2]
        u = -(r_bd[3] * r_tr[2] + r_bd[4] * r_tr[5] + r_bd[5] * r_tr[8])
        u = u if u > 0.0 else 0.0
        # the tilt angle as its chord 2 sin(a / 2) (monotone, slope 1 at 0, cheaper than acos): this term
        # only steers uDEAS; refine.pelvis_projection sets the tilt with the exact angle
        t_null = (data[lw + LW_PRIOR_TR] * abs(x[X_TTR])
                  + data[lw + LW_PRIOR_HP] * (abs(x[X_THP_L]) + abs(x[X_THP_R]))
                  + data[lw + LW_PRIOR_UP] * u * math.sqrt(2.0 - 2.0 * c))
    total = (t_mp + data[lw + LW_COM] * t_com + data[lw + LW_SYM] * t_sym + t_pen
             + data[lw + LW_NULL] * t_null)
    return total, t_mp, t_com, t_sym, t_pen, t_null


@njit(cache=True)
def pose_loss(x, data, work):
    return pose_loss_terms(x, data, work)[0]


# --- least squares for the refinement: residuals and analytic Jacobian ---

@njit(cache=True)
def _cross_into(jac_pt, k, ax, ay, az, px, py, pz, ox, oy, oz):
    """jac_pt[:, k] = a x (p - o)."""
    vx, vy, vz = px - ox, py - oy, pz - oz
    jac_pt[0, k] = ay * vz - az * vy
    jac_pt[1, k] = az * vx - ax * vz
    jac_pt[2, k] = ax * vy - ay * vx


@njit(cache=True)
def _col(r, c):
    return r[c], r[3 + c], r[6 + c]


N_PEN = 9             # penalty hinges: the paper's 7 and the two hip adductions
N_HINGE = N_PEN + N_VAR   # penalties + joint limits (19)


@njit(cache=True)
def n_residuals():
    return 2 * N_LM + N_HINGE + N_VAR


@njit(cache=True)
def residuals_jacobian(x, data, res, jac, want_jac):
    """Least-squares residuals (2 per landmark, then penalty hinges) and their Jacobian d res / d x.

    Landmark residuals are sqrt(w_i / sum w) (obs_i - proj_i - t), t the weighted centroid offset, so the
    sum of squares is the weighted mean squared 2D error; hinge residuals are sqrt(weight) times the
    penalty of eqs. (9)-(11) (zero inside the thresholds) and sqrt(limit weight) times the distance
    outside the joint limits.
    """
    fixed = data[D_FIXED:D_FIXED + N_FIXED]
    pts_b = np.empty((N_POINTS, 3))
    pts_c = np.empty((N_POINTS, 3))
    model_points(x, data, pts_b, pts_c)
    proj = np.empty((N_LM, 3))
    project(x, pts_c, data, proj)
    h = data[D_DIMS + DM_H]
    g = x[X_GAMMA]
    persp = data[D_PROJ] != 0.0
    fnx, fny = data[D_PROJ + 1], data[D_PROJ + 2]
    off = (data[D_PROJ + 3], data[D_PROJ + 4])
    sw = 0.0
    for i in range(N_LM):
        sw += data[D_W + i]
    if sw <= 0.0:
        sw = 1.0
    # residual r_ic = b_ic - a_ic T_c with b = observed - model (no translation), a = d(model)/dT
    a_ = np.empty((N_LM, 2))
    b_ = np.empty((N_LM, 2))
    t_ = np.zeros(2)
    nn = np.zeros(2)
    dd = np.zeros(2)
    for i in range(N_LM):
        w = data[D_W + i]
        for c in range(2):
            if persp:
                a_[i, c] = (fnx if c == 0 else fny) * proj[i, 2]
                b_[i, c] = data[D_OBS + 2 * i + c] + off[c] - proj[i, c]
            else:
                a_[i, c] = 1.0
                b_[i, c] = data[D_OBS + 2 * i + c] - proj[i, c]
            nn[c] += w * a_[i, c] * b_[i, c]
            dd[c] += w * a_[i, c] * a_[i, c]
    for c in range(2):
        t_[c] = nn[c] / dd[c] if dd[c] > 0.0 else 0.0
    for i in range(N_LM):
        sq = math.sqrt(data[D_W + i] / sw)
        res[2 * i] = sq * (b_[i, 0] - a_[i, 0] * t_[0])
        res[2 * i + 1] = sq * (b_[i, 1] - a_[i, 1] * t_[1])
    # hinge residuals
    lw = D_LW
    th = D_TH
    base = 2 * N_LM
    hw = np.empty(N_PEN)
    hv = np.empty(N_PEN)
    hk = np.empty(N_PEN, dtype=np.int64)
    hs = np.empty(N_PEN)  # d(penalty)/d(x) sign
    hk[0] = X_TTR
    hv[0] = p_sn(x[X_TTR], data[th])
    hs[0] = -1.0
    hw[0] = data[lw + LW_SAG_TR]
    hk[1] = X_PTR
    hv[1] = p_d(x[X_PTR], -data[th + 1], data[th + 1])
    hs[1] = -1.0 if x[X_PTR] < 0 else 1.0
    hw[1] = data[lw + LW_COR_TR]
    hk[2] = X_STR
    hv[2] = p_d(x[X_STR], -data[th + 2], data[th + 2])
    hs[2] = -1.0 if x[X_STR] < 0 else 1.0
    hw[2] = data[lw + LW_TRAN_TR]
    hk[3] = X_TSH_L
    hv[3] = p_sn(x[X_TSH_L], data[th + 3])
    hs[3] = -1.0
    hw[3] = data[lw + LW_SAG_SH]
    hk[4] = X_TSH_R
    hv[4] = p_sn(x[X_TSH_R], data[th + 3])
    hs[4] = -1.0
    hw[4] = data[lw + LW_SAG_SH]
    hk[5] = X_PSH_L
    hv[5] = p_sp(x[X_PSH_L], data[th + 4])
    hs[5] = 1.0
    hw[5] = data[lw + LW_COR_SH]
    hk[6] = X_PSH_R
    hv[6] = p_sp(x[X_PSH_R], data[th + 4])
    hs[6] = 1.0
    hw[6] = data[lw + LW_COR_SH]
    hk[7] = X_PHP_L
    hv[7] = p_sp(x[X_PHP_L], data[th + 5])
    hs[7] = 1.0
    hw[7] = data[lw + LW_COR_HP]
    hk[8] = X_PHP_R
    hv[8] = p_sp(x[X_PHP_R], data[th + 5])
    hs[8] = 1.0
    hw[8] = data[lw + LW_COR_HP]
    for q in range(N_PEN):
        res[base + q] = math.sqrt(hw[q]) * hv[q]
    wl = math.sqrt(data[lw + LW_LIMIT])
    for k in range(N_VAR):
        res[base + N_PEN + k] = wl * p_d(x[k], data[D_LIM_LO + k], data[D_LIM_HI + k])
    pb = base + N_HINGE
    lam = math.sqrt(data[D_PRIOR]) if data[D_PRIOR] > 0.0 else 0.0
    for k in range(N_VAR):
        sig = data[D_PRIOR_SIG + k]
        if sig > 0.0 and lam > 0.0:
            p = int(data[D_PRIOR_PARTNER + k])
            v = x[k] - (x[p] if p >= 0 else 0.0)
            res[pb + k] = lam * (v - data[D_PRIOR_MU + k]) / sig
        else:
            res[pb + k] = 0.0
    if not want_jac:
        return
    # --- Jacobian of the camera-axes landmark positions: jp[i] is 3 x 19 ---
    jp = np.zeros((N_LM, 3, N_VAR))
    r_bd = body_rot(x[X_TBD], x[X_PBD], x[X_SBD])
    rz_ = mm(r0(), rz(x[X_SBD]))
    rzx = mm(rz_, rx(-x[X_PBD]))
    a_psi = _col(r0(), 2)
    ax = _col(rz_, 0)
    a_phi = (-ax[0], -ax[1], -ax[2])
    a_theta = _col(rzx, 1)
    for i in range(N_LM):
        px, py, pz = pts_c[i, 0], pts_c[i, 1], pts_c[i, 2]
        _cross_into(jp[i], X_SBD, a_psi[0], a_psi[1], a_psi[2], px, py, pz, 0.0, 0.0, 0.0)
        _cross_into(jp[i], X_PBD, a_phi[0], a_phi[1], a_phi[2], px, py, pz, 0.0, 0.0, 0.0)
        _cross_into(jp[i], X_TBD, a_theta[0], a_theta[1], a_theta[2], px, py, pz, 0.0, 0.0, 0.0)
    # torso: Ry(ttr) Rx(-ptr) Rz(str) about the origin; affects shoulders, elbows, wrists
    r1 = mm(r_bd, ry(x[X_TTR]))
    r2 = mm(r1, rx(-x[X_PTR]))
    a_t = _col(r_bd, 1)
    a_p = _col(r1, 0)
    a_p = (-a_p[0], -a_p[1], -a_p[2])
    a_s = _col(r2, 2)
    r_tr_c = mm(r2, rz(x[X_STR]))
    for i in (P_SH_L, P_SH_R, P_EL_L, P_EL_R, P_WR_L, P_WR_R):
        px, py, pz = pts_c[i, 0], pts_c[i, 1], pts_c[i, 2]
        _cross_into(jp[i], X_TTR, a_t[0], a_t[1], a_t[2], px, py, pz, 0.0, 0.0, 0.0)
        _cross_into(jp[i], X_PTR, a_p[0], a_p[1], a_p[2], px, py, pz, 0.0, 0.0, 0.0)
        _cross_into(jp[i], X_STR, a_s[0], a_s[1], a_s[2], px, py, pz, 0.0, 0.0, 0.0)
    for k in range(2):
        s = 1.0 if k == 0 else -1.0
        ish, iel, iwr = P_SH_L + k, P_EL_L + k, P_WR_L + k
        xt = X_TSH_L if k == 0 else X_TSH_R
        xp = X_PSH_L if k == 0 else X_PSH_R
        xe = X_TEL_L if k == 0 else X_TEL_R
        # shoulder: R_tr Ry(-tsh) Rx(-s psh)
        a1 = _col(r_tr_c, 1)
        a1 = (-a1[0], -a1[1], -a1[2])
        ra = mm(r_tr_c, ry(-x[xt]))
        a2 = _col(ra, 0)
        a2 = (-s * a2[0], -s * a2[1], -s * a2[2])
        rua = mm(ra, rx(-s * x[xp]))
        a3 = _col(rua, 1)
        a3 = (-a3[0], -a3[1], -a3[2])
        ox, oy, oz = pts_c[ish, 0], pts_c[ish, 1], pts_c[ish, 2]
        for i in (iel, iwr):
            px, py, pz = pts_c[i, 0], pts_c[i, 1], pts_c[i, 2]
            _cross_into(jp[i], xt, a1[0], a1[1], a1[2], px, py, pz, ox, oy, oz)
            _cross_into(jp[i], xp, a2[0], a2[1], a2[2], px, py, pz, ox, oy, oz)
        _cross_into(jp[iwr], xe, a3[0], a3[1], a3[2], pts_c[iwr, 0], pts_c[iwr, 1], pts_c[iwr, 2],
                    pts_c[iel, 0], pts_c[iel, 1], pts_c[iel, 2])
    for k in range(2):
        s = 1.0 if k == 0 else -1.0
        ihp, ikn, ian = P_HP_L + k, P_KN_L + k, P_AN_L + k
        xt = X_THP_L if k == 0 else X_THP_R
        xp = X_PHP_L if k == 0 else X_PHP_R
        xk = X_TKN_L if k == 0 else X_TKN_R
        psi_hp = fixed[F_PSIHP_L] if k == 0 else fixed[F_PSIHP_R]
        a1 = _col(r_bd, 1)
        a1 = (-a1[0], -a1[1], -a1[2])
        ra = mm(r_bd, ry(-x[xt]))
        a2 = _col(ra, 0)
        a2 = (-s * a2[0], -s * a2[1], -s * a2[2])
        rth = mm(mm(ra, rx(-s * x[xp])), rz(-s * psi_hp))
        a3 = _col(rth, 1)
        ox, oy, oz = pts_c[ihp, 0], pts_c[ihp, 1], pts_c[ihp, 2]
        for i in (ikn, ian):
            px, py, pz = pts_c[i, 0], pts_c[i, 1], pts_c[i, 2]
            _cross_into(jp[i], xt, a1[0], a1[1], a1[2], px, py, pz, ox, oy, oz)
            _cross_into(jp[i], xp, a2[0], a2[1], a2[2], px, py, pz, ox, oy, oz)
        _cross_into(jp[ian], xk, a3[0], a3[1], a3[2], pts_c[ian, 0], pts_c[ian, 1], pts_c[ian, 2],
                    pts_c[ikn, 0], pts_c[ikn, 1], pts_c[ikn, 2])
    # --- derivatives of the model projection (jq) and of the translation coefficient (ja): 2 x 19 each ---
    jq = np.zeros((N_LM, 2, N_VAR))
    ja = np.zeros((N_LM, 2, N_VAR))
    if not persp:
        for i in range(N_LM):
            for c in range(2):
                for k in range(1, N_VAR):
                    jq[i, c, k] = g * jp[i, c, k] / h
                jq[i, c, X_GAMMA] = pts_c[i, c] / h
    else:
        tz = fny * h / g
        dtz = -tz / g
        for i in range(N_LM):
            zz = tz + pts_c[i, 2]
            if zz < 1e-3 * tz:
                zz = 1e-3 * tz
            z2 = zz * zz
            for c in range(2):
                fn = fnx if c == 0 else fny
                for k in range(1, N_VAR):
                    jq[i, c, k] = fn * (jp[i, c, k] / zz - pts_c[i, c] * jp[i, 2, k] / z2)
                    ja[i, c, k] = -fn * jp[i, 2, k] / z2
                jq[i, c, X_GAMMA] = -fn * pts_c[i, c] * dtz / z2
                ja[i, c, X_GAMMA] = -fn * dtz / z2
    # d r_ic = -dq_ic - da_ic T_c - a_ic dT_c,  T = N / D,  dT = (dN D - N dD) / D^2
    for c in range(2):
        for k in range(N_VAR):
            dn = 0.0
            dD = 0.0
            for i in range(N_LM):
                w = data[D_W + i]
                dn += w * (ja[i, c, k] * b_[i, c] - a_[i, c] * jq[i, c, k])
                dD += 2.0 * w * a_[i, c] * ja[i, c, k]
            dt = (dn * dd[c] - nn[c] * dD) / (dd[c] * dd[c]) if dd[c] > 0.0 else 0.0
            for i in range(N_LM):
                sq = math.sqrt(data[D_W + i] / sw)
                jac[2 * i + c, k] = sq * (-jq[i, c, k] - ja[i, c, k] * t_[c] - a_[i, c] * dt)
    for q in range(N_HINGE):
        for k in range(N_VAR):
            jac[base + q, k] = 0.0
    for q in range(N_PEN):
        if hv[q] > 0.0:
            jac[base + q, hk[q]] = math.sqrt(hw[q]) * hs[q]
    for k in range(N_VAR):
        v = x[k]
        if v < data[D_LIM_LO + k]:
            jac[base + N_PEN + k, k] = -wl
        elif v >= data[D_LIM_HI + k]:
            jac[base + N_PEN + k, k] = wl
    for q in range(N_VAR):
        for k in range(N_VAR):
            jac[pb + q, k] = 0.0
        sig = data[D_PRIOR_SIG + q]
        if sig > 0.0 and lam > 0.0:
            jac[pb + q, q] = lam / sig
            p = int(data[D_PRIOR_PARTNER + q])
            if p >= 0:
                jac[pb + q, p] = -lam / sig


@njit(cache=True)
def sum_sq(res):
    acc = 0.0
    for v in res:
        acc += v * v
    return acc


def empty_work() -> np.ndarray:
    """A fresh work array for :func:`pose_loss` (the trig table starts empty)."""
    work = np.zeros((W_ROWS, 3))
    work[W_TRIG:, 0] = np.nan
    return work
