"""The FitResult of a solved frame (interfaces.md section 2): variables and joint angles in degrees, the 12
joints in camera axes (metres, mid-hip origin), ``root_cam_m`` when known, and the fit's diagnostics. The
numbers come from one kernel (fitting.reported); this module names them."""

from __future__ import annotations

import numpy as np

from posed.fitting import layout as L
from posed.fitting import problem as P
from posed.fitting.depth_term import DepthFit
from posed.fitting.measured import Measured
from posed.fitting.reported import ANGLES, JOINTS, N_REPORTED, ROTATIONS, reported_values
from posed.fitting.result import (
    JOINT_3D_NAMES,
    JOINT_ANGLE_NAMES,
    SHOULDER_ROTATION_NAMES,
    VARIABLE_NAMES,
    FitResult,
)
from posed.fitting.vertical import camera_body_angles

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


# the joint variables (eq. (6) indices 4..18: trunk, hips, knees, shoulders, elbows) and a tolerance for "at a
# joint limit": the refinement clamps a variable to the limit exactly (fitting.problem.LIMIT_LO/HI)
_JOINT_VARIABLES = range(4, 19)
_AT_LIMIT_RAD = 1e-4
_EXTENSION_STOPS = {"theta_kn_l", "theta_kn_r", "theta_el_l", "theta_el_r"}   # 0: straight, a real pose


def at_limit(x: np.ndarray) -> list[str]:
    """The joint variables of solution ``x`` (kernel units) held at a joint limit of the refinement: the fit
    wanted the angle further than the model allows, so the value is the clamp's, not a measurement. A knee or
    an elbow at 0 (straight) is not one: full extension is a pose people hold."""
    out = []
    for i in _JOINT_VARIABLES:
        name = VARIABLE_NAMES[i]
        at_lo = abs(x[i] - P.LIMIT_LO_RAD[i]) < _AT_LIMIT_RAD and name not in _EXTENSION_STOPS
        if at_lo or abs(x[i] - P.LIMIT_HI_RAD[i]) < _AT_LIMIT_RAD:
            out.append(name)
    return out


def assemble(seq: int, t: float, x: np.ndarray, frame: P.Frame, fixed_deg: np.ndarray, *, loss: float,
             mp: float, fit_ms: float, mode: str, evals: int, udeas_s: float, missing: list[str], gamma: float,
             depth: DepthFit | None, measured: Measured | None = None, rotation: P.Rotation = False,
             lens_assumed: bool = False, level: np.ndarray | None = None) -> FitResult:
    """The result of solution ``x`` (kernel units) of ``frame``; ``gamma`` the reported size factor, ``depth``
    the depth term at ``x`` (None without depth), ``measured`` what the frame's landmarks measured
    (fitting.measured; None: judged from ``missing`` alone); ``rotation``: the upper arms' rotations were
    searched (reported as ``shoulder_rotation_deg``); ``lens_assumed``: the perspective frame's intrinsics
    were an assumed lens (camera_model.Intrinsics.assume): ``lens`` says so and ``root_cam_m``, metres
    through a lens nobody measured, is left out; ``level``: the level frame R_CL ``x``'s body angles are taken
    against (fitting.vertical; None: the camera's own), reported against the camera as always."""
    values = np.empty(N_REPORTED)
    data = frame.data
    if level is not None:   # the same body, its angles against the camera: the kernels' data without the level
        x = camera_body_angles(x, level)
        data = data.copy()
        data[L.D_LEVEL:L.D_LEVEL + 10] = 0.0
    known, *root = reported_values(x, data, fixed_deg, 0.0 if depth is None else depth.root_z,
                                   depth is not None, values)
    v = values.tolist()
    variables = {"gamma": round(gamma, 5)}
    variables.update(zip(VARIABLE_NAMES[1:], v[1:ANGLES], strict=True))
    angles = dict(zip(JOINT_ANGLE_NAMES, v[ANGLES:JOINTS], strict=True))
    xyz = v[JOINTS:ROTATIONS]
    j3 = dict(zip(JOINT_3D_NAMES, zip(xyz[0::3], xyz[1::3], xyz[2::3], strict=True), strict=True))
    extra = {"mode": mode, "projection": "perspective" if frame.perspective else "orthographic",
             "err2d": float(f"{mp:.6g}"), "err2d_px": float(f"{mp * frame.scale_px:.4g}"), "evals": evals,
             "udeas_ms": float(f"{udeas_s * 1e3:.4g}")}
    if frame.perspective:
        extra["lens"] = "assumed" if lens_assumed else "given"
    if level is not None:   # the body angles' down was gravity, not the camera's +y (fitting.vertical)
        extra["vertical"] = "gravity"
        extra["down"] = [round(float(v), 5) for v in level[:, 1]]
    if any(P.arms(rotation)):
        extra["shoulder_rotation_deg"] = dict(zip(SHOULDER_ROTATION_NAMES, v[ROTATIONS:], strict=True))
    if depth is not None:
        extra["depth_inliers"] = depth.inliers
    if known and not lens_assumed:  # perspective through the camera's own lens: where the person is
        extra["root_cam_m"] = [round(root[0], 4), round(root[1], 4), round(root[2], 4)]
    if missing:
        extra["missing"] = missing
        extra["unobserved"] = unobserved(missing)
    clamped = at_limit(x)
    if clamped:   # a clamp's value, not a measurement: listed, and left out of what the frame measured
        extra["at_limit"] = clamped
        if measured is not None:
            measured = Measured(measured.landmarks, tuple(a for a in measured.angles if a not in clamped),
                                measured.joints)
    return FitResult(seq=seq, t=t, ok=True, loss=float(f"{loss:.6g}"), fit_ms=float(f"{fit_ms:.4g}"),
                     variables=variables, joint_angles_deg=angles, joints_3d=j3, extra=extra, measured=measured)
