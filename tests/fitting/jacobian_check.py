"""The analytic Jacobian of the refinement's residuals (fitting.jacobian) against central finite differences."""

import numpy as np

from posed.fitting import jacobian as JAC
from posed.fitting import layout as L
from posed.fitting import problem as P


def rendered_frame(pose, dims, cfg, perspective: bool, weights: dict[int, float] | None = None, **pack_kw):
    """``pose`` (bench.simulate) rendered through the simulator's level camera (pinhole when ``perspective``,
    else orthographic) and packed as the fitter packs a frame: landmark weights (``weights`` overrides some,
    by landmark index), reference scale, the camera's intrinsics when perspective; ``pack_kw`` to P.pack."""
    from posed.bench import simulate as S

    camera = S.LevelCamera(model="pinhole")   # 600, 600, 320, 240 at 640x480
    lm = S.render(pose, dims=dims, camera=camera if perspective else None)
    xy, w, _ = P.landmark_weights(lm, cfg)
    for i, v in (weights or {}).items():
        w[i] = v
    return P.pack(xy, w, dims, cfg, P.reference_scale(xy, w, dims),
                  camera.intrinsics((640, 480)) if perspective else None, **pack_kw)


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
