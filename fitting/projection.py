"""numba kernels: the camera model, camera axes (metres, origin at the mid-hip) -> normalized image units
(pixels divided by scale_px, the reference pixels per metre times the body height; see fitting.problem).
``cache=True``.

Orthographic (the paper's reprojection): (g X / H, g Y / H). Perspective (pinhole, camera-centred normalized
units): the mid-hip sits at depth Tz = fn_y H / g in front of the camera and a point at depth Z' = Tz + Z
projects to (fn_x X / Z', fn_y Y / Z'). In both the translation of the body in the image is not part of the
projection: it is solved by weighted least squares where the 2D error is formed (fitting.loss.mpjpe,
fitting.jacobian), exactly, because the residual is linear in it. Tested through the loss against NumPy.
``image_scale``: the local image scale at each landmark, for fitting.proportions.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L

MIN_DEPTH = 1e-3  # a point is kept at least this fraction of Tz in front of the camera


@njit(cache=True)
def project(x, pts_c, data, out2):
    """Model image coordinates of the 12 landmarks before the translation, normalized units: out2 (12 x 3).

    Orthographic: (g X / H, g Y / H, unused 0). Perspective: (fn_x X / Z', fn_y Y / Z', 1 / Z'), with
    1 / Z' the coefficient of the lateral translation's effect (per unit of fn).
    """
    h = data[L.D_DIMS + L.DM_H]
    g = x[L.X_GAMMA]
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        for i in range(L.N_LM):
            out2[i, 0] = g * pts_c[i, 0] / h
            out2[i, 1] = g * pts_c[i, 1] / h
            out2[i, 2] = 0.0
    else:
        fnx, fny = data[L.D_PROJ + L.PJ_FN_X], data[L.D_PROJ + L.PJ_FN_Y]
        tz = fny * h / g
        for i in range(L.N_LM):
            zz = tz + pts_c[i, 2]
            if zz < MIN_DEPTH * tz:
                zz = MIN_DEPTH * tz
            out2[i, 0] = fnx * pts_c[i, 0] / zz
            out2[i, 1] = fny * pts_c[i, 1] / zz
            out2[i, 2] = 1.0 / zz


@njit(cache=True)
def project_w(x, data, work):
    """project() on the loss work array: camera-axes rows W_PTS_C.. -> rows W_PROJ.. (perspective: 1 / Z'
    in column 2)."""
    h = data[L.D_DIMS + L.DM_H]
    g = x[L.X_GAMMA]
    c0 = L.W_PTS_C
    p0 = L.W_PROJ
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        k = g / h
        for i in range(L.N_LM):
            work[p0 + i, 0] = k * work[c0 + i, 0]
            work[p0 + i, 1] = k * work[c0 + i, 1]
    else:
        fnx, fny = data[L.D_PROJ + L.PJ_FN_X], data[L.D_PROJ + L.PJ_FN_Y]
        tz = fny * h / g
        for i in range(L.N_LM):
            zz = tz + work[c0 + i, 2]
            if zz < MIN_DEPTH * tz:
                zz = MIN_DEPTH * tz
            inv = 1.0 / zz
            work[p0 + i, 0] = fnx * work[c0 + i, 0] * inv
            work[p0 + i, 1] = fny * work[c0 + i, 1] * inv
            work[p0 + i, 2] = inv


@njit(cache=True)
def image_scale(x, data):
    """The image scale at each of the 12 body landmarks of solution ``x``: normalized image units per metre of
    a small displacement parallel to the image plane at the landmark's fitted depth, (12,) array.
    Orthographic: ``g / H`` everywhere; perspective: ``fn_y / Z'`` (Z' the landmark's depth, metres, not
    nearer than MIN_DEPTH x the root's, as :func:`project` clamps it)."""
    h = data[L.D_DIMS + L.DM_H]
    g = x[L.X_GAMMA]
    out = np.empty(L.N_LM)
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        for i in range(L.N_LM):
            out[i] = g / h
        return out
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, data, pts_b, pts_c)
    fn_y = data[L.D_PROJ + L.PJ_FN_Y]
    tz = fn_y * h / g
    lim = MIN_DEPTH * tz
    for i in range(L.N_LM):
        z = tz + pts_c[i, 2]
        out[i] = fn_y / (z if (z >= lim or z != z) else lim)   # NumPy's maximum: a NaN depth stays NaN
    return out
