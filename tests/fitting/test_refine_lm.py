"""The Levenberg-Marquardt kernel (fitting.refine.levenberg_marquardt) against a plain NumPy reference of the
same method: Marquardt's diagonal damping, Nielsen's gain-ratio update, variables held at a bound whose
descent direction leaves the box, and the relative stopping rule."""

import numpy as np
import pytest

from posed.fitting import jacobian as JAC
from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting import refine
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.result import MODEL_VARIABLE_NAMES

DIMS = BodyDimensions.from_height(1.65)
EPS = np.finfo(float).eps


def reference_lm(x0, lo, hi, data, max_iter):
    """The kernel's method written with NumPy (np.linalg.solve for the damped normal equations)."""
    m = JAC.n_residuals()

    def rj(x):
        res, jac = np.empty(m), np.empty((m, x.size))
        JAC.residuals_jacobian(x, data, res, jac, True)
        return res, jac

    x = np.clip(x0, lo, hi)
    res, jac = rj(x)
    cost, lam, nu = res @ res, 1e-3, 2.0
    for _ in range(max_iter):
        a, g = jac.T @ jac, jac.T @ res
        held = ((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0))
        free = ~held
        accepted = None
        for _ in range(12):
            damped = a + np.diag(lam * np.maximum(np.diag(a), 1e-9) + 1e-12)
            step = np.zeros_like(x)
            step[free] = np.linalg.solve(damped[np.ix_(free, free)], -g[free])
            x_new = np.clip(x + step, lo, hi)
            r_new = np.empty(m)
            JAC.residuals_jacobian(x_new, data, r_new, np.empty((1, 1)), False)
            c_new = r_new @ r_new
            if c_new < cost:
                h = x_new - x
                pred = -(h @ (2.0 * g + a @ h))
                rho = (cost - c_new) / pred if pred > 0 else 0.0
                lam = max(lam * max(1 / 3, 1 - (2 * rho - 1) ** 3), 1e-9)
                nu = 2.0
                accepted = (x_new, c_new)
                break
            lam *= nu
            nu *= 2.0
        if accepted is None:
            break
        gain = cost - accepted[1]
        x, cost = accepted
        res, jac = rj(x)
        if gain <= 1e-13 + refine.REL_TOL * cost:
            break
    return x, cost


def frame_and_start(seed):
    from posed.bench import simulate as S

    cfg = FitConfig()
    truth = S.pose("bend_grab", 40.0)
    lm = S.render(truth, dims=DIMS, noise_px=3.0, seed=seed)
    xy, w, _ = P.landmark_weights(lm, cfg)
    frame = P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS), None)
    x_true = P.to_radians(np.array([1.0] + [truth.angle(n) for n in MODEL_VARIABLE_NAMES[1:]]))
    rng = np.random.default_rng(seed)
    return frame.data, x_true + rng.normal(0.0, 0.15, x_true.size) * (np.arange(x_true.size) > 0)


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("max_iter", [1, 3])
def test_kernel_matches_numpy_reference(seed, max_iter):
    """The same iterates as the reference (few iterations: the comparison is of the method, not of where
    rounding differences lead after many steps). Bound: the damped systems' condition number times a few
    float64 ulps, per unit of step, carried through max_iter steps."""
    data, x0 = frame_and_start(seed)
    lo, hi = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD
    out = np.empty(L.N_VAR)
    cost, it, _ = refine.levenberg_marquardt(x0, lo, hi, data, max_iter, out)
    x_ref, cost_ref = reference_lm(x0, lo, hi, data, max_iter)
    assert it <= max_iter
    m = JAC.n_residuals()
    res, jac = np.empty(m), np.empty((m, L.N_VAR))
    JAC.residuals_jacobian(np.clip(x0, lo, hi), data, res, jac, True)
    a = jac.T @ jac
    cond = np.linalg.cond(a + np.diag(1e-3 * np.maximum(np.diag(a), 1e-9)))
    bound = 64 * cond * EPS * max(1.0, np.abs(x0).max()) * max_iter
    np.testing.assert_allclose(out, x_ref, rtol=0, atol=bound)
    assert cost == pytest.approx(cost_ref, rel=1e-6)


def test_reused_work_arrays_give_the_fresh_result():
    """levenberg_marquardt_into on one set of work arrays (fitting.refine.lm_work), reused across starts,
    frames and iteration limits, gives every result to the last bit that a fresh allocation gives: nothing
    of one refinement leaks into the next (as best_hypothesis reuses them for all of a frame's hypotheses)."""
    lo, hi = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD
    lw = refine.lm_work()
    for seed in (1, 2, 3, 4):
        data, x0 = frame_and_start(seed)
        for max_iter in (0, 1, 5, 100):
            fresh, reused = np.empty(L.N_VAR), np.empty(L.N_VAR)
            got_fresh = refine.levenberg_marquardt(x0, lo, hi, data, max_iter, fresh)
            got_reused = refine.levenberg_marquardt_into(x0, lo, hi, data, max_iter, reused, lw)
            assert got_reused == got_fresh
            assert reused.tobytes() == fresh.tobytes()


def test_variable_at_a_bound_is_held_and_cost_falls():
    """A start with the left knee pushed past its limit: the result stays inside the box and lowers the
    cost; a variable pinned at its bound by the data does not stall the others (the reference agrees)."""
    data, x0 = frame_and_start(4)
    lo, hi = P.LIMIT_LO_RAD, P.LIMIT_HI_RAD
    x0 = x0.copy()
    x0[L.X_TKN_L] = lo[L.X_TKN_L] - 0.3
    m = JAC.n_residuals()
    r0 = np.empty(m)
    JAC.residuals_jacobian(np.clip(x0, lo, hi), data, r0, np.empty((1, 1)), False)
    out = np.empty(L.N_VAR)
    cost, it, _ = refine.levenberg_marquardt(x0, lo, hi, data, 30, out)
    assert np.all(out >= lo) and np.all(out <= hi)
    assert cost < r0 @ r0
    x_ref, cost_ref = reference_lm(x0, lo, hi, data, 30)
    # both stop by the same relative rule; their final costs agree to within that rule's tolerance
    assert cost == pytest.approx(cost_ref, rel=10 * refine.REL_TOL)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_normal_equations_match_numpy(seed):
    """refine.normal_equations (dense landmark rows, sparse hinge and prior rows, depth rows) against
    J'J and J'r. Bound: each entry is a sum of N_RES products, a few ulps of the largest product each."""
    data, x0 = frame_and_start(seed)
    data = data.copy()
    rng = np.random.default_rng(seed)
    data[L.D_DEPTH:L.D_DEPTH + L.N_LM] = rng.normal(0.0, 0.2, L.N_LM)
    data[L.D_DEPTH_W:L.D_DEPTH_W + L.N_LM] = rng.uniform(0.0, 3.0, L.N_LM) * (rng.random(L.N_LM) < 0.8)
    data[L.D_PRIOR] = 0.5
    data[L.D_PRIOR_SIG:L.D_PRIOR_SIG + L.N_VAR] = P.PRIOR_SIG_RAD
    data[L.D_PRIOR_PARTNER:L.D_PRIOR_PARTNER + L.N_VAR] = P.PRIOR_PARTNER
    x0 = x0.copy()
    x0[L.X_TKN_L] = P.LIMIT_LO_RAD[L.X_TKN_L] - 0.2  # a joint-limit hinge row
    m = JAC.n_residuals()
    res, jac = np.empty(m), np.empty((m, L.N_VAR))
    JAC.residuals_jacobian(x0, data, res, jac, True)
    a, g = np.empty((L.N_VAR, L.N_VAR)), np.empty(L.N_VAR)
    refine.normal_equations(jac, res, a, g, np.empty(L.N_VAR, dtype=np.int64))
    scale = np.abs(jac).max() * max(np.abs(jac).max(), np.abs(res).max())
    np.testing.assert_allclose(a, jac.T @ jac, rtol=0, atol=4 * m * EPS * scale)
    np.testing.assert_allclose(g, jac.T @ res, rtol=0, atol=4 * m * EPS * scale)
    assert np.array_equal(a, a.T)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_cholesky_solve_matches_numpy(seed):
    """refine.cholesky_solve (reciprocal diagonal, caller work arrays) against np.linalg.solve on damped
    normal matrices of the refinement; a matrix that is not positive definite is refused. Bound: the
    condition number times a few ulps."""
    data, x0 = frame_and_start(seed)
    m = JAC.n_residuals()
    res, jac = np.empty(m), np.empty((m, L.N_VAR))
    JAC.residuals_jacobian(x0, data, res, jac, True)
    a = jac.T @ jac
    a += np.diag(1e-3 * np.maximum(np.diag(a), 1e-9) + 1e-12)
    b = np.random.default_rng(seed).normal(size=L.N_VAR)
    out = np.empty(L.N_VAR)
    assert refine.cholesky_solve(a, b, out)
    ref = np.linalg.solve(a, b)
    np.testing.assert_allclose(out, ref, rtol=0, atol=64 * np.linalg.cond(a) * EPS * np.abs(ref).max())
    bad = a.copy()
    bad[5, 5] = -1.0
    assert not refine.cholesky_solve(bad, b, out)
