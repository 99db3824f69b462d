"""The mid-hip's camera-frame position (fitting.root) computed the plain way, the reference of the kernel's
tests (tests/fitting/test_root.py) and of the assembled result's ``root_cam_m`` (tests/fitting/test_assemble.py)."""

from __future__ import annotations


def reference_root(x, data, pts_c, root_z=None):
    """fitting.root.root_position's sums in plain Python floats: (X, Y, Z) in metres, or None when not known."""
    from posed.fitting import layout as L
    from posed.fitting.projection import MIN_DEPTH

    if data[L.D_PROJ + L.PJ_MODE] == L.PROJ_ORTHOGRAPHIC:
        return None
    w = data[L.D_W:L.D_W + L.N_LM].tolist()
    if not any(v > 0 for v in w):
        return None
    fn = (float(data[L.D_PROJ + L.PJ_FN_X]), float(data[L.D_PROJ + L.PJ_FN_Y]))
    off = (float(data[L.D_PROJ + L.PJ_OFF_X]), float(data[L.D_PROJ + L.PJ_OFF_Y]))
    tz = fn[1] * float(data[L.D_DIMS + L.DM_H]) / float(x[L.X_GAMMA]) if root_z is None else float(root_z)
    obs = data[L.D_OBS:L.D_OBS + 2 * L.N_LM].tolist()
    num, den = [0.0, 0.0], [0.0, 0.0]
    for i, (wi, p) in enumerate(zip(w, pts_c[:L.N_LM].tolist(), strict=True)):
        z = max(tz + p[2], MIN_DEPTH * tz)
        for c in (0, 1):
            a = fn[c] / z
            b = obs[2 * i + c] + off[c] - fn[c] * p[c] / z
            num[c] += wi * a * b
            den[c] += wi * a * a
    return num[0] / den[0], num[1] / den[1], float(tz)
