"""Where the person is: the mid-hip's position in the camera frame (``root_cam_m``, interfaces.md section 2).

Camera frame: metres, x image right, y image down, z away from the camera (along the optical axis).

Known only with the perspective model (the camera's intrinsics): the fit's size factor then fixes the depth,
because a body of the person's height ``H`` (configured or calibrated) that spans ``g`` normalized units
stands at ``Tz = fn_y H / g`` (fitting.projection), and the lateral position is the translation the 2D error
is minimised over: the weighted least-squares ``T`` in ``obs_i + off = fn (X_i + T) / (Tz + Z_i)``
(fitting.loss.mpjpe), solved here again in float64 for the final solution. With a depth camera the
measured depth replaces the size's (a wrong body height then no longer misplaces the person). An orthographic
fit (no intrinsics) has no scale to metres: not known. The sums run in a numba kernel (``cache=True``; tested
against the plain-Python sums of tests/fitting/root_reference.py).
"""

from __future__ import annotations

from numba import njit

from posed.fitting import layout as L
from posed.fitting.projection import MIN_DEPTH


@njit(cache=True)
def root_position(x, data, pts_c, root_z, measured):
    """The mid-hip's camera-frame position for solution ``x`` (kernel units) of the problem ``data``: (known,
    X, Y, Z) in metres, known False (and zeros) for the orthographic model or when no landmark is used.
    ``pts_c``: the 12 body landmarks in camera axes (metres, mid-hip origin), as fitting.forward_kinematics
    model_points gives them; ``root_z``: the mid-hip's depth measured by a depth camera
    (fitting.depth_term), used instead of the one from the person's size when ``measured``. Called by
    fitting.reported for every result."""
    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        return False, 0.0, 0.0, 0.0
    used = False
    for i in range(L.N_LM):
        used = used or data[L.D_W + i] > 0
    if not used:
        return False, 0.0, 0.0, 0.0
    fn = (data[L.D_PROJ + L.PJ_FN_X], data[L.D_PROJ + L.PJ_FN_Y])
    off = (data[L.D_PROJ + L.PJ_OFF_X], data[L.D_PROJ + L.PJ_OFF_Y])
    tz = root_z if measured else fn[1] * data[L.D_DIMS + L.DM_H] / x[L.X_GAMMA]
    num = [0.0, 0.0]
    den = [0.0, 0.0]
    for i in range(L.N_LM):
        wi = data[L.D_W + i]
        z = tz + pts_c[i, 2]
        if MIN_DEPTH * tz > z:   # z = max(Tz + Z_i, MIN_DEPTH Tz)
            z = MIN_DEPTH * tz
        for c in range(2):
            a = fn[c] / z                                        # d(image)/d(T) of landmark i on axis c
            b = data[L.D_OBS + 2 * i + c] + off[c] - fn[c] * pts_c[i, c] / z
            num[c] += wi * a * b
            den[c] += wi * a * a
    return True, num[0] / den[0], num[1] / den[1], tz
