"""numba kernels: forward kinematics of the humanoid model on flat arrays, the numba twin of the NumPy
reference :mod:`fitting.kinematics` (tested against it point by point). ``cache=True``.

Two entry points:

* :func:`model_points`: the 19 model points (layout ``P_*``) of ``x`` in the pelvis frame and in camera
  axes, metres, origin at the mid-hip, into caller arrays (:func:`model_points_into`: with a reusable work
  array). Used by the refinement and the Jacobian.
* :func:`update_trig` + :func:`fk_update`: the same on the loss work array (layout ``W_*``,
  :func:`empty_work`), incrementally: the trig table keeps each angle with its cosine and sine, and only the
  point groups whose angles changed since the last call are recomputed (uDEAS moves one variable at a time).

Rotations (fitting.kinematics has the conventions): body R_CB = R0 Rz(psi_bd) Rx(-phi_bd) Ry(theta_bd);
lumbar Ry(theta_tr) Rx(-phi_tr) Rz(psi_tr); shoulder Ry(-theta_sh) Rx(-s phi_sh), elbow Ry(-theta_el);
hip Ry(-theta_hp) Rx(-s phi_hp) Rz(-s psi_hp), knee Ry(theta_kn), ankle Ry(-theta_an) Rx(-s phi_an);
head Ry(theta_hd) Rz(psi_hd); s = +1 left, -1 right. Segments hang along -z of their frames.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.rotations import body_rot, level_rot, mm, put_point, r0, rx, rx_cs, ry, ry_cs, rz, rz_cs

# Dempster / Winter segment masses (fitting.body.SEGMENT_MASS, fractions of body mass) and centre-of-mass
# positions along the segments (fractions of their length from the proximal joint).
M_TRUNK, M_HEAD, M_UA, M_FA, M_HAND = 0.497, 0.081, 0.028, 0.016, 0.006
M_TH, M_SK, M_FOOT = 0.100, 0.0465, 0.0145
C_UA, C_FA, C_HAND, C_TH, C_SK = 0.436, 0.430, 0.506, 0.433, 0.433
HEAD_EAR_HEIGHT = 0.112  # ear midpoint above the mid-shoulder, fraction of body height (fitting.kinematics)

# Groups of angle slots whose change moves the same points (bit masks).
G_BODY, G_TORSO, G_ARM_L, G_ARM_R, G_LEG_L, G_LEG_R = 1, 2, 4, 8, 16, 32
G_ALL = 63

# Trig-table slots of the fixed angles.
S_THD, S_PHD = L.N_VAR + L.F_THD, L.N_VAR + L.F_PHD
S_PSIHP_L, S_TAN_L, S_PAN_L = L.N_VAR + L.F_PSIHP_L, L.N_VAR + L.F_TAN_L, L.N_VAR + L.F_PAN_L
S_PSIHP_R, S_TAN_R, S_PAN_R = L.N_VAR + L.F_PSIHP_R, L.N_VAR + L.F_TAN_R, L.N_VAR + L.F_PAN_R


@njit(cache=True)
def _slot_group(k):
    """The point group that trig-table slot ``k`` moves."""
    if k == L.X_TBD or k == L.X_PBD or k == L.X_SBD:
        return G_BODY
    if k == L.X_TTR or k == L.X_PTR or k == L.X_STR or k == S_THD or k == S_PHD:
        return G_TORSO
    if k == L.X_TSH_L or k == L.X_TEL_L or k == L.X_PSH_L or k == L.X_PSISH_L:
        return G_ARM_L
    if k == L.X_TSH_R or k == L.X_TEL_R or k == L.X_PSH_R or k == L.X_PSISH_R:
        return G_ARM_R
    if k == L.X_THP_L or k == L.X_TKN_L or k == L.X_PHP_L or k == S_PSIHP_L or k == S_TAN_L or k == S_PAN_L:
        return G_LEG_L
    if k == L.X_THP_R or k == L.X_TKN_R or k == L.X_PHP_R or k == S_PSIHP_R or k == S_TAN_R or k == S_PAN_R:
        return G_LEG_R
    return 0


@njit(cache=True)
def update_trig(x, data, work):
    """Refresh the trig table for the angles that changed since the last call (uDEAS moves one at a time);
    returns the bit mask of the point groups that moved (G_ALL when the body dimensions changed)."""
    mask = 0
    sig = 0.0
    for k in range(L.N_DIMS):
        sig += data[L.D_DIMS + k] * (k + 1)
    if work[L.W_SIG, 0] != sig:
        work[L.W_SIG, 0] = sig
        mask = G_ALL
    # the level frame turns the whole body: its own signature (column 1)
    lv = 0.0
    for k in range(10):
        lv += data[L.D_LEVEL + k] * (k + 1.5)
    if work[L.W_SIG, 1] != lv:
        work[L.W_SIG, 1] = lv
        mask |= G_BODY
    for k in range(1, L.N_VAR):
        r = L.W_TRIG + k
        if work[r, 0] != x[k]:
            work[r, 0] = x[k]
            work[r, 1] = math.cos(x[k])
            work[r, 2] = math.sin(x[k])
            mask |= _slot_group(k)
    for k in range(L.N_FIXED):
        r = L.W_TRIG + L.N_VAR + k
        a = data[L.D_FIXED + k]
        if work[r, 0] != a:
            work[r, 0] = a
            work[r, 1] = math.cos(a)
            work[r, 2] = math.sin(a)
            mask |= _slot_group(L.N_VAR + k)
    return mask


@njit(cache=True)
def _ry_slot(work, k, sign):
    """Ry(sign * angle of slot k) from the trig table."""
    r = L.W_TRIG + k
    return ry_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def _rx_slot(work, k, sign):
    r = L.W_TRIG + k
    return rx_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def _rz_slot(work, k, sign):
    r = L.W_TRIG + k
    return rz_cs(work[r, 1], sign * work[r, 2])


@njit(cache=True)
def store_rot(work, row, r):
    """Rows row .. row + 2 of ``work`` = the rotation ``r``."""
    for i in range(3):
        for j in range(3):
            work[row + i, j] = r[3 * i + j]


@njit(cache=True)
def load_rot(work, row):
    """The rotation stored at rows row .. row + 2 of ``work``."""
    return (work[row, 0], work[row, 1], work[row, 2], work[row + 1, 0], work[row + 1, 1], work[row + 1, 2],
            work[row + 2, 0], work[row + 2, 1], work[row + 2, 2])


@njit(cache=True)
def body_rot_w(data, work):
    """R_CB = R_CL R0 Rz(psi_bd) Rx(-phi_bd) Ry(theta_bd) from the trig table (R_CL: the level frame of
    ``data``, fitting.rotations.level_rot; the body angles are taken against it)."""
    r_z = mm(mm(level_rot(data, L.D_LEVEL), r0()), _rz_slot(work, L.X_SBD, 1.0))
    return mm(mm(r_z, _rx_slot(work, L.X_PBD, -1.0)), _ry_slot(work, L.X_TBD, 1.0))


@njit(cache=True)
def torso_rot_w(work):
    """Pelvis from torso: Ry(theta_tr) Rx(-phi_tr) Rz(psi_tr), from the trig table."""
    return mm(mm(_ry_slot(work, L.X_TTR, 1.0), _rx_slot(work, L.X_PTR, -1.0)), _rz_slot(work, L.X_STR, 1.0))


@njit(cache=True)
def _fk_torso(data, work):
    """Mid-shoulder, head (ear midpoint) and shoulders in the pelvis frame; stores the torso rotation."""
    b = L.W_PTS_B
    l_tr = data[L.D_DIMS + L.DM_TRUNK]
    r_tr = torso_rot_w(work)
    store_rot(work, L.W_RTR, r_tr)
    put_point(work, b + L.P_MIDSH, 0.0, 0.0, 0.0, r_tr, 0.0, 0.0, l_tr)
    r_hd = mm(mm(r_tr, _ry_slot(work, S_THD, 1.0)), _rz_slot(work, S_PHD, 1.0))
    m = b + L.P_MIDSH
    put_point(work, b + L.P_HEAD, work[m, 0], work[m, 1], work[m, 2], r_hd, 0.0, 0.0,
              HEAD_EAR_HEIGHT * data[L.D_DIMS + L.DM_H])
    put_point(work, b + L.P_SH_L, 0.0, 0.0, 0.0, r_tr, 0.0, data[L.D_DIMS + L.DM_SH], l_tr)
    put_point(work, b + L.P_SH_R, 0.0, 0.0, 0.0, r_tr, 0.0, -data[L.D_DIMS + L.DM_SH], l_tr)


@njit(cache=True)
def _fk_arm(k, data, work):
    """Elbow and wrist of arm ``k`` (0 left, 1 right) in the pelvis frame (needs the torso)."""
    b = L.W_PTS_B
    s = 1.0 if k == 0 else -1.0
    i_sh, i_el, i_wr = b + L.P_SH_L + k, b + L.P_EL_L + k, b + L.P_WR_L + k
    x_tsh = L.X_TSH_L if k == 0 else L.X_TSH_R
    x_psh = L.X_PSH_L if k == 0 else L.X_PSH_R
    x_tel = L.X_TEL_L if k == 0 else L.X_TEL_R
    x_psish = L.X_PSISH_L if k == 0 else L.X_PSISH_R
    l_ua, l_fa = data[L.D_DIMS + L.DM_UA], data[L.D_DIMS + L.DM_FA]
    r_tr = load_rot(work, L.W_RTR)
    r_ua = mm(mm(mm(r_tr, _ry_slot(work, x_tsh, -1.0)), _rx_slot(work, x_psh, -s)), _rz_slot(work, x_psish, -s))
    put_point(work, i_el, work[i_sh, 0], work[i_sh, 1], work[i_sh, 2], r_ua, 0.0, 0.0, -l_ua)
    r_fa = mm(r_ua, _ry_slot(work, x_tel, -1.0))
    put_point(work, i_wr, work[i_el, 0], work[i_el, 1], work[i_el, 2], r_fa, 0.0, 0.0, -l_fa)


@njit(cache=True)
def _fk_leg(k, data, work):
    """Hip, knee, ankle, heel and toe of leg ``k`` (0 left, 1 right) in the pelvis frame."""
    b = L.W_PTS_B
    s = 1.0 if k == 0 else -1.0
    i_hp, i_kn, i_an = b + L.P_HP_L + k, b + L.P_KN_L + k, b + L.P_AN_L + k
    i_heel, i_toe = b + L.P_HEEL_L + k, b + L.P_TOE_L + k
    x_thp = L.X_THP_L if k == 0 else L.X_THP_R
    x_php = L.X_PHP_L if k == 0 else L.X_PHP_R
    x_tkn = L.X_TKN_L if k == 0 else L.X_TKN_R
    s_psihp = S_PSIHP_L if k == 0 else S_PSIHP_R
    s_tan = S_TAN_L if k == 0 else S_TAN_R
    s_pan = S_PAN_L if k == 0 else S_PAN_R
    work[i_hp, 0] = 0.0
    work[i_hp, 1] = s * data[L.D_DIMS + L.DM_HP]
    work[i_hp, 2] = 0.0
    l_th, l_sk = data[L.D_DIMS + L.DM_TH], data[L.D_DIMS + L.DM_SK]
    r_th = mm(mm(_ry_slot(work, x_thp, -1.0), _rx_slot(work, x_php, -s)), _rz_slot(work, s_psihp, -s))
    put_point(work, i_kn, work[i_hp, 0], work[i_hp, 1], work[i_hp, 2], r_th, 0.0, 0.0, -l_th)
    r_sk = mm(r_th, _ry_slot(work, x_tkn, 1.0))
    put_point(work, i_an, work[i_kn, 0], work[i_kn, 1], work[i_kn, 2], r_sk, 0.0, 0.0, -l_sk)
    r_ft = mm(mm(r_sk, _ry_slot(work, s_tan, -1.0)), _rx_slot(work, s_pan, -s))
    l_ft, h_an = data[L.D_DIMS + L.DM_FOOT], data[L.D_DIMS + L.DM_ANK]
    put_point(work, i_heel, work[i_an, 0], work[i_an, 1], work[i_an, 2], r_ft, -0.25 * l_ft, 0.0, -h_an)
    put_point(work, i_toe, work[i_an, 0], work[i_an, 1], work[i_an, 2], r_ft, 0.75 * l_ft, 0.0, -h_an)


@njit(cache=True)
def _com(data, work):
    """Whole-body centre of mass from the pelvis-frame points (Dempster fractions), into row P_COM."""
    b = L.W_PTS_B
    hand = C_HAND * 0.5 * data[L.D_DIMS + L.DM_HAND] / data[L.D_DIMS + L.DM_FA]
    for c in range(3):
        acc = M_TRUNK * 0.5 * work[b + L.P_MIDSH, c] + M_HEAD * work[b + L.P_HEAD, c]
        for k in range(2):
            sh, el, wr = work[b + L.P_SH_L + k, c], work[b + L.P_EL_L + k, c], work[b + L.P_WR_L + k, c]
            acc += (M_UA * (sh + C_UA * (el - sh)) + M_FA * (el + C_FA * (wr - el))
                    + M_HAND * (wr + hand * (wr - el)))
            hp, kn, an = work[b + L.P_HP_L + k, c], work[b + L.P_KN_L + k, c], work[b + L.P_AN_L + k, c]
            acc += M_TH * (hp + C_TH * (kn - hp)) + M_SK * (kn + C_SK * (an - kn))
            # ankle + R_ft (0.225 l_foot, 0, -0.5 h_ankle) = 0.5 ankle + 0.15 heel + 0.35 toe
            heel, toe = work[b + L.P_HEEL_L + k, c], work[b + L.P_TOE_L + k, c]
            acc += M_FOOT * (0.5 * an + 0.15 * heel + 0.35 * toe)
        work[b + L.P_COM, c] = acc


@njit(cache=True)
def _rotate_rows(work, r_bd, i0, i1):
    """Camera-axes rows of points i0 .. i1 - 1 = R_CB times their pelvis-frame rows."""
    for i in range(i0, i1):
        b = L.W_PTS_B + i
        put_point(work, L.W_PTS_C + i, 0.0, 0.0, 0.0, r_bd, work[b, 0], work[b, 1], work[b, 2])


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
        store_rot(work, L.W_RBD, body_rot_w(data, work))
    r_bd = load_rot(work, L.W_RBD)
    if mask & G_BODY:
        _rotate_rows(work, r_bd, 0, L.N_POINTS)
        return
    if mask & G_TORSO:
        _rotate_rows(work, r_bd, L.P_SH_L, L.P_SH_R + 1)
        _rotate_rows(work, r_bd, L.P_HEAD, L.P_MIDSH + 1)
    if mask & G_ARM_L:
        _rotate_rows(work, r_bd, L.P_EL_L, L.P_EL_L + 1)
        _rotate_rows(work, r_bd, L.P_WR_L, L.P_WR_L + 1)
    if mask & G_ARM_R:
        _rotate_rows(work, r_bd, L.P_EL_R, L.P_EL_R + 1)
        _rotate_rows(work, r_bd, L.P_WR_R, L.P_WR_R + 1)
    if mask & G_LEG_L:
        for i in (L.P_HP_L, L.P_KN_L, L.P_AN_L, L.P_HEEL_L, L.P_TOE_L):
            _rotate_rows(work, r_bd, i, i + 1)
    if mask & G_LEG_R:
        for i in (L.P_HP_R, L.P_KN_R, L.P_AN_R, L.P_HEEL_R, L.P_TOE_R):
            _rotate_rows(work, r_bd, i, i + 1)
    if mask:
        _rotate_rows(work, r_bd, L.P_COM, L.P_COM + 1)


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
    return load_rot(work, L.W_RTR)


@njit(cache=True)
def model_points(x, data, pts_b, pts_c):
    """Model points of ``x`` in the pelvis frame and in camera axes (19 x 3 each, metres)."""
    model_points_into(x, data, pts_b, pts_c, empty_work())


@njit(cache=True)
def model_points_into(x, data, pts_b, pts_c, work):
    """:func:`model_points` on a caller work array (:func:`empty_work`; reusable, its trig table is
    recomputed in full)."""
    for r in range(L.W_TRIG, L.W_ROWS):
        work[r, 0] = np.nan
    update_trig(x, data, work)
    fk_work(data, work)
    r_bd = body_rot_w(data, work)
    for i in range(L.N_POINTS):
        for c in range(3):
            pts_b[i, c] = work[L.W_PTS_B + i, c]
        b = L.W_PTS_B + i
        put_point(pts_c, i, 0.0, 0.0, 0.0, r_bd, work[b, 0], work[b, 1], work[b, 2])


@njit(cache=True)
def torso_uprightness(x):
    """cos of the torso's inclination from vertical, clipped at 0 (1 upright, 0 horizontal or below); the body
    angles of ``x`` are taken against the level frame (R_CL aside), whose -y is up."""
    r_tr = mm(mm(ry(x[L.X_TTR]), rx(-x[L.X_PTR])), rz(x[L.X_STR]))
    r = mm(body_rot(x[L.X_TBD], x[L.X_PBD], x[L.X_SBD]), r_tr)
    c = -r[5]  # -(R_LB R_tr)[1, 2]: the torso's z axis against up (-y of the level frame)
    return c if c > 0.0 else 0.0


@njit(cache=True)
def empty_work():
    """A fresh (W_ROWS, 3) work array for :func:`fitting.loss.pose_loss` and :func:`model_points_into` (the
    trig table starts empty)."""
    work = np.zeros((L.W_ROWS, 3))
    for r in range(L.W_TRIG, L.W_ROWS):
        work[r, 0] = np.nan
    return work
