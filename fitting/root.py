"""Where the person is: the mid-hip's position in the camera frame (``root_cam_m``, interfaces.md section 2).

Camera frame: metres, x image right, y image down, z away from the camera (along the optical axis).

Known only with the perspective model (the camera's intrinsics): the fit's size factor then fixes the depth,
because a body of the person's height ``H`` (configured or calibrated) that spans ``g`` normalized units
stands at ``Tz = fn_y H / g`` (fitting.projection), and the lateral position is the translation the 2D error
is minimised over: the weighted least-squares ``T`` in ``obs_i + off = fn (X_i + T) / (Tz + Z_i)``
(fitting.loss.mpjpe), solved here again in float64 for the final solution. With a depth camera the
measured depth replaces the size's (a wrong body height then no longer misplaces the person). An orthographic
fit (no intrinsics) has no scale to metres: None.
"""

from __future__ import annotations

import numpy as np

from fitting import layout as L
from fitting.projection import MIN_DEPTH


def root_in_camera(x: np.ndarray, data: np.ndarray, pts_c: np.ndarray,
                   root_z: float | None = None) -> tuple[float, float, float] | None:
    """The mid-hip's camera-frame position in metres for solution ``x`` (kernel units) of the problem ``data``;
    ``pts_c``: the 12 body landmarks in camera axes (metres, mid-hip origin), as fitting.forward_kinematics
    model_points gives them; ``root_z``: the mid-hip's depth measured by a depth camera (fitting.depth_term),
    which then replaces the one from the person's size. None for the orthographic model or when no landmark
    is used."""
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        return None
    w = data[L.D_W:L.D_W + L.N_LM].tolist()   # plain floats: this runs on every frame
    if not any(v > 0 for v in w):
        return None
    fn = (float(data[L.D_PROJ + L.PJ_FN_X]), float(data[L.D_PROJ + L.PJ_FN_Y]))
    off = (float(data[L.D_PROJ + L.PJ_OFF_X]), float(data[L.D_PROJ + L.PJ_OFF_Y]))
    tz = fn[1] * float(data[L.D_DIMS + L.DM_H]) / float(x[L.X_GAMMA]) if root_z is None else float(root_z)
    obs = data[L.D_OBS:L.D_OBS + 2 * L.N_LM].tolist()
    pts = pts_c[:L.N_LM].tolist()
    num, den = [0.0, 0.0], [0.0, 0.0]
    for i, (wi, p) in enumerate(zip(w, pts, strict=True)):
        z = max(tz + p[2], MIN_DEPTH * tz)
        for c in (0, 1):
            a = fn[c] / z                                        # d(image)/d(T) of landmark i on axis c
            b = obs[2 * i + c] + off[c] - fn[c] * p[c] / z
            num[c] += wi * a * b
            den[c] += wi * a * a
    return num[0] / den[0], num[1] / den[1], float(tz)
