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
    deg = np.round(P.to_degrees(x), 4).tolist()
    variables = dict(zip(VARIABLE_NAMES, deg, strict=True))
    variables["gamma"] = round(gamma, 5)
    angles = dict.fromkeys(JOINT_ANGLE_NAMES, 0.0)
    for name, v in zip(FIXED_NAMES, np.round(fixed_deg, 4).tolist(), strict=True):
        angles[name] = v
    for name in VARIABLE_NAMES[4:]:
        angles[name] = variables[name]
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points(x, frame.data, pts_b, pts_c)
    j3 = {"mid_hip": (0.0, 0.0, 0.0)}
    for name, row in zip(BODY_LANDMARK_NAMES, np.round(pts_c[:12], 5).tolist(), strict=True):
        j3[name] = tuple(row)
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
