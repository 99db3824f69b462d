"""numba kernels: the pose loss of the paper's section 4.2, the cost uDEAS minimizes.

    L(x) = MPJPE + w_com CoMD + w_sym (|theta_hp_l - theta_hp_r| + |theta_kn_l - theta_kn_r|)
           + penalties + w_null Prior_tilt

evaluated on the loss work array (fitting.forward_kinematics.empty_work) that caches the trig table and the
model points between calls. ``cache=True``; angles radians, 2D errors in normalized image units (fractions
of the apparent body height), the CoM deviation in leg lengths. Each term is tested against a plain NumPy
reference in ``tests/fitting/test_loss.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.forward_kinematics import fk_update, load_rot, update_trig
from posed.fitting.penalties import penalties
from posed.fitting.projection import project_w
from posed.fitting.rotations import level_rot, mm, transposed


@njit(cache=True)
def mpjpe(proj, r0, data):
    """Eq. (7): weighted mean 2D distance after the best translation (normalized units).

    ``proj[r0 + i]`` holds landmark i's model projection from :func:`fitting.projection.project`.
    Orthographic: the best translation aligns the weighted centroids. Perspective: the lateral translation
    of the body enters as a_i T with a_i = fn / Z'_i; its weighted least-squares value is used.
    """
    sw = 0.0
    for i in range(L.N_LM):
        sw += data[L.D_W + i]
    if sw <= 0.0:
        return 0.0
    acc = 0.0
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        tx = 0.0
        ty = 0.0
        for i in range(L.N_LM):
            w = data[L.D_W + i]
            tx += w * (data[L.D_OBS + 2 * i] - proj[r0 + i, 0])
            ty += w * (data[L.D_OBS + 2 * i + 1] - proj[r0 + i, 1])
        tx /= sw
        ty /= sw
        for i in range(L.N_LM):
            w = data[L.D_W + i]
            if w > 0.0:
                dx = data[L.D_OBS + 2 * i] - proj[r0 + i, 0] - tx
                dy = data[L.D_OBS + 2 * i + 1] - proj[r0 + i, 1] - ty
                acc += w * math.sqrt(dx * dx + dy * dy)
        return acc / sw
    fnx, fny = data[L.D_PROJ + L.PJ_FN_X], data[L.D_PROJ + L.PJ_FN_Y]
    offx, offy = data[L.D_PROJ + L.PJ_OFF_X], data[L.D_PROJ + L.PJ_OFF_Y]
    nx = 0.0
    dx_ = 0.0
    ny = 0.0
    dy_ = 0.0
    for i in range(L.N_LM):
        w = data[L.D_W + i]
        inv = proj[r0 + i, 2]
        ax = fnx * inv
        ay = fny * inv
        bx = data[L.D_OBS + 2 * i] + offx - proj[r0 + i, 0]
        by = data[L.D_OBS + 2 * i + 1] + offy - proj[r0 + i, 1]
        nx += w * ax * bx
        dx_ += w * ax * ax
        ny += w * ay * by
        dy_ += w * ay * ay
    tx = nx / dx_
    ty = ny / dy_
    for i in range(L.N_LM):
        w = data[L.D_W + i]
        if w > 0.0:
            inv = proj[r0 + i, 2]
            ex = data[L.D_OBS + 2 * i] + offx - proj[r0 + i, 0] - fnx * inv * tx
            ey = data[L.D_OBS + 2 * i + 1] + offy - proj[r0 + i, 1] - fny * inv * ty
            acc += w * math.sqrt(ex * ex + ey * ey)
    return acc / sw


# the points a person can rest on, in support mode
SUPPORT_CANDIDATES = (L.P_HEEL_L, L.P_HEEL_R, L.P_TOE_L, L.P_TOE_R, L.P_KN_L, L.P_KN_R, L.P_HP_L, L.P_HP_R,
                      L.P_WR_L, L.P_WR_R, L.P_EL_L, L.P_EL_R, L.P_SH_L, L.P_SH_R, L.P_HEAD)


@njit(cache=True)
def com_deviation(pts_c, r0, data):
    """CoM deviation (the paper's missing eq. 8), normalized by the leg length l_leg.

    ``pts_c[r0 + P_*]``: model points in camera axes. Gravity is +y of the level frame (the camera's own
    axes unless ``data`` gives one: fitting.rotations.level_rot), the floor its x-z plane. ``feet`` mode
    (paper): the distance on the floor from the CoM to the centre of the supporting feet (heel and toe
    points within ``contact`` of the lowest foot point). ``support`` mode: every body point within
    ``contact`` of the lowest one supports (feet, knees, hips, hands, elbows, shoulders, head; the hips also
    when they are not above their knees: a seat); the deviation is the distance of the CoM from the centre
    of the support points' bounding box (x-z) beyond ``margin`` times half its diagonal (zero for a stable
    pose).
    """
    if data[L.D_LEVEL] != 0.0:   # the points in the level frame: p_L = R_CL^T p_C
        r = level_rot(data, L.D_LEVEL)
        lv = np.empty((L.N_POINTS, 3))
        for i in range(L.N_POINTS):
            px, py, pz = pts_c[r0 + i, 0], pts_c[r0 + i, 1], pts_c[r0 + i, 2]
            for c in range(3):
                lv[i, c] = r[c] * px + r[3 + c] * py + r[6 + c] * pz
        pts_c = lv
        r0 = 0
    l_leg = data[L.D_DIMS + L.DM_TH] + data[L.D_DIMS + L.DM_SK] + data[L.D_DIMS + L.DM_ANK]
    contact = data[L.D_LW + L.LW_CONTACT] * data[L.D_DIMS + L.DM_H]
    if data[L.D_LW + L.LW_COM_MODE] == L.COM_FEET:
        ymax = -1e300
        for i in range(L.P_HEEL_L, L.P_TOE_R + 1):
            if pts_c[r0 + i, 1] > ymax:
                ymax = pts_c[r0 + i, 1]
        sx = 0.0
        sz = 0.0
        n = 0
        for i in range(L.P_HEEL_L, L.P_TOE_R + 1):
            if pts_c[r0 + i, 1] >= ymax - contact:
                sx += pts_c[r0 + i, 0]
                sz += pts_c[r0 + i, 2]
                n += 1
        dx = pts_c[r0 + L.P_COM, 0] - sx / n
        dz = pts_c[r0 + L.P_COM, 2] - sz / n
        return math.sqrt(dx * dx + dz * dz) / l_leg
    ymax = -1e300
    for i in SUPPORT_CANDIDATES:
        y = pts_c[r0 + i, 1]
        if y > ymax:
            ymax = y
    floor = ymax - contact
    seat = data[L.D_LW + L.LW_SEAT] > 0.0
    seat_l = seat and pts_c[r0 + L.P_HP_L, 1] >= pts_c[r0 + L.P_KN_L, 1] - contact
    seat_r = seat and pts_c[r0 + L.P_HP_R, 1] >= pts_c[r0 + L.P_KN_R, 1] - contact
    x0 = 1e300
    x1 = -1e300
    z0 = 1e300
    z1 = -1e300
    for i in SUPPORT_CANDIDATES:
        if pts_c[r0 + i, 1] >= floor or (i == L.P_HP_L and seat_l) or (i == L.P_HP_R and seat_r):
            px = pts_c[r0 + i, 0]
            pz = pts_c[r0 + i, 2]
            x0 = min(x0, px)
            x1 = max(x1, px)
            z0 = min(z0, pz)
            z1 = max(z1, pz)
    dx = pts_c[r0 + L.P_COM, 0] - 0.5 * (x0 + x1)
    dz = pts_c[r0 + L.P_COM, 2] - 0.5 * (z0 + z1)
    half = 0.5 * math.sqrt((x1 - x0) ** 2 + (z1 - z0) ** 2)
    dev = math.sqrt(dx * dx + dz * dz) - data[L.D_LW + L.LW_MARGIN] * half
    return dev / l_leg if dev > 0.0 else 0.0


@njit(cache=True)
def pose_loss_terms(x, data, work):
    """Loss of section 4.2 and its terms: (total, mpjpe, comd, sym, penalties, null prior).

    ``work``: a (W_ROWS, 3) array from :func:`fitting.forward_kinematics.empty_work`, reused between calls
    (its trig table and points are a cache).
    """
    mask = update_trig(x, data, work)
    fk_update(mask, data, work)
    r_tr = load_rot(work, L.W_RTR)
    r_bd = load_rot(work, L.W_RBD)
    project_w(x, data, work)
    lw = L.D_LW
    t_mp = mpjpe(work, L.W_PROJ, data)
    t_com = com_deviation(work, L.W_PTS_C, data) if data[lw + L.LW_COM] > 0.0 else 0.0
    t_sym = abs(x[L.X_THP_L] - x[L.X_THP_R]) + abs(x[L.X_TKN_L] - x[L.X_TKN_R])
    t_pen = penalties(x, data)
    t_null = 0.0
    if data[lw + L.LW_NULL] > 0.0:
        if data[L.D_LEVEL] != 0.0:   # the body against the level frame: R_LB = R_CL^T R_CB
            r_bd = mm(transposed(level_rot(data, L.D_LEVEL)), r_bd)
        # pelvis tilt from vertical: cos = (pelvis up) . (world up) = -R_LB[1, 2]
        c = min(max(-r_bd[5], -1.0), 1.0)
        # torso uprightness: -(R_LB R_tr)[1, 2]
        u = -(r_bd[3] * r_tr[2] + r_bd[4] * r_tr[5] + r_bd[5] * r_tr[8])
        u = u if u > 0.0 else 0.0
        # the tilt angle as its chord 2 sin(a / 2) (monotone, slope 1 at 0, cheaper than acos): this term
        # only steers uDEAS; refine.pelvis_projection sets the tilt with the exact angle
        t_null = (data[lw + L.LW_PRIOR_TR] * abs(x[L.X_TTR])
                  + data[lw + L.LW_PRIOR_HP] * (abs(x[L.X_THP_L]) + abs(x[L.X_THP_R]))
                  + data[lw + L.LW_PRIOR_UP] * u * math.sqrt(2.0 - 2.0 * c))
    total = (t_mp + data[lw + L.LW_COM] * t_com + data[lw + L.LW_SYM] * t_sym + t_pen
             + data[lw + L.LW_NULL] * t_null)
    return total, t_mp, t_com, t_sym, t_pen, t_null


@njit(cache=True)
def pose_loss(x, data, work):
    """The total of :func:`pose_loss_terms`."""
    return pose_loss_terms(x, data, work)[0]
