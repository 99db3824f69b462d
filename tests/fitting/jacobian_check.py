"""The analytic Jacobian of the refinement's residuals (fitting.jacobian) against central finite differences."""

import numpy as np

from posed.fitting import jacobian as JAC
from posed.fitting import layout as L


def assert_jacobian_matches_finite_differences(x: np.ndarray, data: np.ndarray) -> np.ndarray:
    """Assert the analytic Jacobian at ``x`` equals central differences (away from the hinge rows' kinks);
    returns the residuals at ``x``."""
    m = JAC.n_residuals()
    res, jac = np.empty(m), np.empty((m, L.N_VAR))
    JAC.residuals_jacobian(x, data, res, jac, True)
    num = np.empty_like(jac)
    eps = 1e-6
    for k in range(L.N_VAR):
        rp, rm = np.empty(m), np.empty(m)
        xp, xm = x.copy(), x.copy()
        xp[k] += eps
        xm[k] -= eps
        JAC.residuals_jacobian(xp, data, rp, np.empty((1, 1)), False)
        JAC.residuals_jacobian(xm, data, rm, np.empty((1, 1)), False)
        num[:, k] = (rp - rm) / (2 * eps)
    ok = np.abs(res) > 1e-9   # hinge rows have kinks: compare away from them
    ok[: 2 * L.N_LM] = True
    np.testing.assert_allclose(jac[ok], num[ok], atol=2e-6, rtol=1e-5)
    return res
