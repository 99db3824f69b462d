"""The depth term (fitting.depth_term) evaluated on a solution and written into the refinement's depth rows
(``R_DEPTH``, fitting.jacobian): per landmark a target depth relative to the mid-hip and a weight, re-solved
from each start (iteratively reweighted least squares with Geman-McClure's weights)."""

from __future__ import annotations

import numpy as np

from fitting import forward_kinematics as FK
from fitting import jacobian as JAC
from fitting import layout as L
from fitting.depth_term import DepthFit, depth_fit


def depth_fit_at(x: np.ndarray, data: np.ndarray, depth: np.ndarray) -> DepthFit | None:
    """The depth term of solution ``x`` (kernel units) of problem ``data`` against the measured ``depth`` at
    the 12 body landmarks (metres, NaN unknown)."""
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, data, pts_b, pts_c)
    return depth_fit(pts_c[:L.N_LM, 2], depth)


def set_depth_rows(data: np.ndarray, fit: DepthFit | None, weight: float) -> None:
    """Write the depth rows into ``data``: targets from ``fit`` and weights sqrt(weight x robust weight) /
    sigma, so a depth residual of one sigma costs ``weight`` (the refinement's cost units); ``fit`` None (or
    weight 0) turns the rows off."""
    if fit is None or weight <= 0:
        data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = 0.0
        return
    data[L.D_DEPTH:L.D_DEPTH + L.N_LM] = np.nan_to_num(fit.targets)
    data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = np.sqrt(weight * fit.weights) / fit.sigma


def refinement_cost(x: np.ndarray, data: np.ndarray) -> float:
    """The refinement's sum of squares at ``x`` (every residual row of fitting.jacobian)."""
    res = np.empty(L.N_RES)
    JAC.residuals_jacobian(x, data, res, np.empty((1, 1)), False)
    return float(np.dot(res, res))
