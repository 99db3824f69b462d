"""The FitResult of a solved frame (interfaces.md section 2): variables and joint angles in degrees, the 12
joints in camera axes (metres, mid-hip origin), ``root_cam_m`` when known, and the fit's diagnostics."""

from __future__ import annotations

import numpy as np

from fitting import forward_kinematics as FK
from fitting import layout as L
from fitting import problem as P
from fitting.depth_term import DepthFit
from fitting.kinematics import BODY_LANDMARK_NAMES
from fitting.result import JOINT_ANGLE_NAMES, VARIABLE_NAMES, FitResult
from fitting.root import root_in_camera

# the joint angles the model holds fixed (not estimated), in the order of the fitter's fixed values
FIXED_NAMES = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")

_DEPENDS = {  # variables that only these landmarks observe
    "left_elbow": ("theta_sh_l", "phi_sh_l"), "right_elbow": ("theta_sh_r", "phi_sh_r"),
    "left_wrist": ("theta_el_l",), "right_wrist": ("theta_el_r",),
    "left_knee": ("theta_hp_l", "phi_hp_l"), "right_knee": ("theta_hp_r", "phi_hp_r"),
    "left_ankle": ("theta_kn_l",), "right_ankle": ("theta_kn_r",),
}


_NO_ANGLES = dict.fromkeys(JOINT_ANGLE_NAMES, 0.0)   # every joint angle, in order

# Per entry of [x, fixed angles, 12 joints x 3] (rounded_output): the divisor to the reported unit (degrees;
# gamma, the fixed angles and the joints' metres as they are) and 10^decimals of the rounding.
_UNIT = np.concatenate(([1.0], np.full(L.N_VAR - 1, P.DEG), np.ones(L.N_FIXED + 3 * L.N_LM)))
_DECIMALS = np.concatenate((np.full(L.N_VAR + L.N_FIXED, 1e4), np.full(3 * L.N_LM, 1e5)))


def rounded_output(x: np.ndarray, fixed_deg: np.ndarray, joints_m: np.ndarray) -> list[float]:
    """[``x`` in degrees (gamma unitless), ``fixed_deg``, ``joints_m`` (12 x 3, metres) row by row], rounded
    to 4, 4 and 5 decimals: ``np.round`` of each, in one pass with np.round's own steps (times 10^decimals,
    rint, divided by 10^decimals)."""
    v = np.concatenate((x, fixed_deg, joints_m.ravel())) / _UNIT
    v *= _DECIMALS
    np.rint(v, out=v)
    v /= _DECIMALS
    return v.tolist()


def unobserved(missing: list[str]) -> list[str]:
    """The variables no used landmark observes when ``missing`` landmarks are left out."""
    out: list[str] = []
    for name in missing:
        out.extend(_DEPENDS.get(name, ()))
    return out


def assemble(seq: int, t: float, x: np.ndarray, frame: P.Frame, fixed_deg: np.ndarray, *, loss: float,
             mp: float, fit_ms: float, mode: str, evals: int, udeas_s: float, missing: list[str], gamma: float,
             depth: DepthFit | None) -> FitResult:
    """The result of solution ``x`` (kernel units) of ``frame``; ``gamma`` the reported size factor, ``depth``
    the depth term at ``x`` (None without depth)."""
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, frame.data, pts_b, pts_c)
    out = rounded_output(x, fixed_deg, pts_c[:L.N_LM])
    deg, fixed, xyz = out[:L.N_VAR], out[L.N_VAR:L.N_VAR + L.N_FIXED], out[L.N_VAR + L.N_FIXED:]
    variables = dict(zip(VARIABLE_NAMES, deg, strict=True))
    variables["gamma"] = round(gamma, 5)
    angles = _NO_ANGLES.copy()
    angles.update(zip(FIXED_NAMES, fixed, strict=True))
    angles.update(zip(VARIABLE_NAMES[4:], deg[4:], strict=True))
    j3 = {"mid_hip": (0.0, 0.0, 0.0)}
    j3.update(zip(BODY_LANDMARK_NAMES, zip(xyz[0::3], xyz[1::3], xyz[2::3], strict=True), strict=True))
    extra = {"mode": mode, "projection": "perspective" if frame.perspective else "orthographic",
             "err2d": float(f"{mp:.6g}"), "err2d_px": float(f"{mp * frame.scale_px:.4g}"), "evals": evals,
             "udeas_ms": float(f"{udeas_s * 1e3:.4g}")}
    root = root_in_camera(x, frame.data, pts_c, None if depth is None else depth.root_z)
    if depth is not None:
        extra["depth_inliers"] = depth.inliers
    if root is not None:  # perspective (intrinsics known): where the person is, for a robot to go there
        extra["root_cam_m"] = [round(v, 4) for v in root]
    if missing:
        extra["missing"] = missing
        extra["unobserved"] = unobserved(missing)
    return FitResult(seq=seq, t=t, ok=True, loss=float(f"{loss:.6g}"), fit_ms=float(f"{fit_ms:.4g}"),
                     variables=variables, joint_angles_deg=angles, joints_3d=j3, extra=extra)
