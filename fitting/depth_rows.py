"""The depth term (fitting.depth_term) evaluated on a solution and written into the refinement's depth rows
(``R_DEPTH``, fitting.jacobian): per landmark a target depth relative to the mid-hip and a weight, re-solved
from each start (iteratively reweighted least squares with Geman-McClure's weights).

:func:`depth_term_kernel` is the numba twin of :func:`fitting.depth_term.depth_fit` on a solution ``x``
(the forward kinematics, the median vote, the inlier mean and the robust costs in one call, ``cache=True``;
tested against the NumPy function in ``tests/fitting/test_depth_term.py``): the fitter evaluates the term
on every hypothesis, and the NumPy version's per-call overhead was most of the cost of depth.
:func:`set_depth_rows_at` writes the rows from it, :func:`cost_with_depth` is what candidates refined with
different robust weights are compared on; both are single calls for the same reason.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import forward_kinematics as FK
from posed.fitting import jacobian as JAC
from posed.fitting import layout as L
from posed.fitting.depth_term import (
    CAPSULE_RADII,
    CAPSULES,
    DEPTH_RMS_K,
    HIDDEN_MARGIN_M,
    MIN_DEPTHS,
    SENSOR_DEPTH_CAMERA,
    SURFACE_M,
    SURFACE_SIGMA_M,
    DepthFit,
)

_SURFACE = tuple(float(v) for v in SURFACE_M)  # frozen into the kernel (fitting.jitcache hashes depth_term)
_CAPSULES = np.array(CAPSULES, dtype=np.int64)
_RADII = np.array(CAPSULE_RADII)


@njit(cache=True)
def occluder_front_into(pts_c, data, front):
    """:func:`fitting.depth_term.occluder_front` of the first 12 rows of ``pts_c`` into ``front`` (12), along
    each landmark's observed ray: with perspective projection the slopes ``(u - cx) / fx``, ``(v - cy) / fy``
    of its observed pixel (problem ``data``: observations, weights and camera; a landmark of weight 0 has no
    pixel and is looked at along the ray through the landmarks' centroid), orthographic along the optical
    axis."""
    slope = np.zeros((L.N_LM, 2))
    if data[L.D_PROJ + L.PJ_MODE] != L.PROJ_ORTHOGRAPHIC:
        for i in range(L.N_LM):
            seen = data[L.D_W + i] > 0.0   # an unusable landmark has no pixel: the landmarks' centroid's ray
            ox = data[L.D_OBS + 2 * i] if seen else 0.0
            oy = data[L.D_OBS + 2 * i + 1] if seen else 0.0
            slope[i, 0] = (ox + data[L.D_PROJ + L.PJ_OFF_X]) / data[L.D_PROJ + L.PJ_FN_X]
            slope[i, 1] = (oy + data[L.D_PROJ + L.PJ_OFF_Y]) / data[L.D_PROJ + L.PJ_FN_Y]
    for i in range(L.N_LM):
        front[i] = np.inf
    for c in range(_CAPSULES.shape[0]):
        a0, a1, b0, b1 = _CAPSULES[c, 0], _CAPSULES[c, 1], _CAPSULES[c, 2], _CAPSULES[c, 3]
        r2 = _RADII[c] * _RADII[c]
        ax = 0.5 * (pts_c[a0, 0] + pts_c[a1, 0])
        ay = 0.5 * (pts_c[a0, 1] + pts_c[a1, 1])
        az = 0.5 * (pts_c[a0, 2] + pts_c[a1, 2])
        ux0 = 0.5 * (pts_c[b0, 0] + pts_c[b1, 0]) - ax
        uy0 = 0.5 * (pts_c[b0, 1] + pts_c[b1, 1]) - ay
        uz = 0.5 * (pts_c[b0, 2] + pts_c[b1, 2]) - az
        for i in range(L.N_LM):
            if i == a0 or i == a1 or i == b0 or i == b1:
                continue
            sx, sy = slope[i, 0], slope[i, 1]   # sheared along landmark i's ray: (x - sx z, y - sy z)
            ux, uy = ux0 - sx * uz, uy0 - sy * uz
            px = pts_c[i, 0] - sx * pts_c[i, 2] - (ax - sx * az)
            py = pts_c[i, 1] - sy * pts_c[i, 2] - (ay - sy * az)
            uu = ux * ux + uy * uy
            s = 0.0
            if uu > 1e-12:
                s = min(max((px * ux + py * uy) / uu, 0.0), 1.0)
            dx = px - s * ux
            dy = py - s * uy
            miss2 = dx * dx + dy * dy
            if miss2 < r2:
                z = az + s * uz - math.sqrt(r2 - miss2)
                if z < pts_c[i, 2] - _SURFACE[i] - HIDDEN_MARGIN_M and z < front[i]:
                    front[i] = z


@njit(cache=True)
def depth_term_kernel(x, data, depth, sensor, targets, weights):
    """:func:`fitting.depth_term.depth_fit` of the landmark depths of solution ``x`` (kernel units) of
    problem ``data`` against the measured ``depth`` (12, metres, NaN unknown) of the ``sensor``
    (fitting.depth_term.SENSOR_DEPTH_CAMERA, or fitting.world_term.SENSOR_WORLD).

    Writes ``targets`` (12, NaN unknown) and ``weights`` (12, 0 unknown) and returns
    (measured count, cost, root_z, inliers, sigma); with fewer than MIN_DEPTHS measurements only the count
    is meaningful (no term)."""
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, data, pts_b, pts_c)
    front = np.empty(L.N_LM)
    if sensor[1] > 0.0:
        occluder_front_into(pts_c, data, front)
    else:
        front[:] = np.inf
    votes = np.empty(L.N_LM)
    n = 0
    for i in range(L.N_LM):
        d = depth[i]
        targets[i] = np.nan
        weights[i] = 0.0
        if np.isfinite(d) and d > 0.0:
            votes[n] = d - front[i] if front[i] < np.inf else d + sensor[0] * _SURFACE[i] - pts_c[i, 2]
            n += 1
    if n < MIN_DEPTHS:
        return n, 0.0, np.nan, 0, np.nan
    srt = np.sort(votes[:n])
    root = srt[n // 2] if n % 2 == 1 else (srt[n // 2 - 1] + srt[n // 2]) / 2.0
    sigma = math.hypot(DEPTH_RMS_K * root * root, SURFACE_SIGMA_M) if not sensor[2] > 0.0 else sensor[2]
    acc = 0.0
    near = 0
    for j in range(n):
        if abs(votes[j] - root) < 3.0 * sigma:
            acc += votes[j]
            near += 1
    if near >= MIN_DEPTHS:
        root = acc / near
    cost = 0.0
    j = 0
    for i in range(L.N_LM):
        d = depth[i]
        if np.isfinite(d) and d > 0.0:
            u = (votes[j] - root) / sigma
            u2 = u * u
            cost += u2 / (1.0 + u2)
            if front[i] == np.inf:   # a hidden joint's depth is the occluder's: no row for the joint
                targets[i] = d + sensor[0] * _SURFACE[i] - root
                weights[i] = 1.0 / (1.0 + u2) ** 2
            j += 1
    return n, cost, root, near, sigma


def depth_fit_at(x: np.ndarray, data: np.ndarray, depth: np.ndarray,
                 sensor: np.ndarray = SENSOR_DEPTH_CAMERA) -> DepthFit | None:
    """The depth term of solution ``x`` (kernel units) of problem ``data`` against the measured ``depth`` at
    the 12 body landmarks (metres, NaN unknown) of the ``sensor``; None with fewer than MIN_DEPTHS
    measurements."""
    targets = np.empty(L.N_LM)
    weights = np.empty(L.N_LM)
    n, cost, root, inliers, sigma = depth_term_kernel(x, data, depth, sensor, targets, weights)
    if n < MIN_DEPTHS:
        return None
    return DepthFit(float(cost), float(root), int(inliers), float(sigma), targets, weights)


@njit(cache=True)
def set_depth_rows_at(x, data, depth, sensor, weight):
    """Write the refinement's depth rows into ``data`` from the depth term of solution ``x``
    (:func:`depth_term_kernel` against the measured ``depth``, 12, metres, NaN unknown, of the ``sensor``):
    each landmark's target
    depth relative to the mid-hip and the weight sqrt(weight x robust weight) / sigma, so a depth residual of
    one sigma costs ``weight`` (the refinement's cost units). Rows off (weights 0) with fewer than
    MIN_DEPTHS depths or ``weight`` <= 0."""
    targets = np.empty(L.N_LM)
    weights = np.empty(L.N_LM)
    n, _, _, _, sigma = depth_term_kernel(x, data, depth, sensor, targets, weights)
    for i in range(L.N_LM):
        if n < MIN_DEPTHS or not weight > 0.0:
            data[L.D_DEPTH_W + i] = 0.0
        else:
            data[L.D_DEPTH + i] = 0.0 if np.isnan(targets[i]) else targets[i]
            data[L.D_DEPTH_W + i] = math.sqrt(weight * weights[i]) / sigma


@njit(cache=True)
def cost_with_depth(x, data, depth, sensor, weight):
    """The refinement's sum of squares at ``x`` without its depth rows (they hold one start's robust weights)
    plus ``weight`` times the depth term's cost at ``x`` against ``depth`` of the ``sensor`` (none with fewer
    than MIN_DEPTHS depths): what candidates refined with different robust weights are compared on."""
    res = np.empty(L.N_RES)
    JAC.residuals_into(x, data, res, JAC.empty_work())
    acc = 0.0
    for r in range(L.R_DEPTH):
        acc += res[r] * res[r]
    targets = np.empty(L.N_LM)
    weights = np.empty(L.N_LM)
    n, cost, _, _, _ = depth_term_kernel(x, data, depth, sensor, targets, weights)
    if n >= MIN_DEPTHS:
        acc += weight * cost
    return acc
