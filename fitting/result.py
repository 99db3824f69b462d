"""The fit result of one frame (interfaces.md section 2): what ``posed fit`` writes and Zenoh carries."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

# The 19 optimization variables of the paper's eq. (6), in its order; degrees except gamma (unitless).
VARIABLE_NAMES = (
    "gamma", "theta_bd", "phi_bd", "psi_bd", "theta_tr", "phi_tr", "psi_tr",
    "theta_hp_l", "theta_kn_l", "theta_hp_r", "theta_kn_r", "theta_sh_l", "theta_el_l", "theta_sh_r",
    "theta_el_r", "phi_hp_l", "phi_hp_r", "phi_sh_l", "phi_sh_r",
)

# The three body angles (orientation of the pelvis in camera axes), degrees; also among VARIABLE_NAMES.
BODY_ANGLE_NAMES = ("theta_bd", "phi_bd", "psi_bd")

# The model's 23 joint angles (paper section 2.2), Vicon sign convention.
JOINT_ANGLE_NAMES = (
    "theta_hd", "psi_hd",
    "theta_sh_l", "phi_sh_l", "theta_sh_r", "phi_sh_r",
    "theta_el_l", "theta_el_r",
    "theta_tr", "phi_tr", "psi_tr",
    "theta_hp_l", "phi_hp_l", "psi_hp_l", "theta_hp_r", "phi_hp_r", "psi_hp_r",
    "theta_kn_l", "theta_kn_r",
    "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r",
)

# joints_3d keys: the mid-hip origin and the 12 body landmarks by MediaPipe name.
JOINT_3D_NAMES = (
    "mid_hip", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
)


@dataclass(frozen=True)
class FitResult:
    """One frame's fit.

    variables: the 19 optimization variables by name (degrees, gamma unitless); joint_angles_deg: the 23
    joint angles; joints_3d: metres, right-handed, camera-aligned, origin at the mid-hip, x image right,
    y image down, z away from the camera. ``ok`` False carries a ``reason`` and may omit the rest.
    ``extra`` keeps additional fields (added freely, never renamed).
    """

    seq: int
    t: float
    ok: bool
    reason: str = ""
    loss: float | None = None
    fit_ms: float | None = None
    variables: dict[str, float] = field(default_factory=dict)
    joint_angles_deg: dict[str, float] = field(default_factory=dict)
    joints_3d: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def root_cam_m(self) -> tuple[float, float, float] | None:
        """The mid-hip in the camera frame, metres (x image right, y image down, z away from the camera), when
        known (the camera's intrinsics and the person's size); None otherwise. Kept in ``extra`` (JSON key
        ``root_cam_m``)."""
        v = self.extra.get("root_cam_m")
        return None if v is None else (float(v[0]), float(v[1]), float(v[2]))

    @classmethod
    def failure(cls, seq: int, t: float, reason: str, **extra: Any) -> FitResult:
        return cls(seq=seq, t=t, ok=False, reason=reason, extra=dict(extra))

    def to_json(self) -> dict:
        out: dict[str, Any] = {"seq": self.seq, "t": self.t, "ok": self.ok}
        if not self.ok:
            out["reason"] = self.reason
        if self.loss is not None:
            out["loss"] = self.loss
        if self.fit_ms is not None:
            out["fit_ms"] = self.fit_ms
        if self.variables:
            out["variables"] = dict(self.variables)
        if self.joint_angles_deg:
            out["joint_angles_deg"] = dict(self.joint_angles_deg)
        if self.joints_3d:
            out["joints_3d"] = {k: list(v) for k, v in self.joints_3d.items()}
        for k, v in self.extra.items():
            out.setdefault(k, v)
        return out

    @classmethod
    def from_json(cls, obj: Any) -> FitResult:
        """Parse a fit result object; raises ValueError naming what is wrong."""
        if not isinstance(obj, dict):
            raise ValueError("a fit result must be a JSON object")
        for key, kind in (("seq", int), ("ok", bool)):
            if not isinstance(obj.get(key), kind) or (kind is int and isinstance(obj.get(key), bool)):
                raise ValueError(f"{key} must be {kind.__name__}, got {obj.get(key)!r}")
        t = obj.get("t")
        if not isinstance(t, (int, float)) or isinstance(t, bool) or not math.isfinite(t):
            raise ValueError(f"t must be a finite number, got {t!r}")
        known = {"seq", "t", "ok", "reason", "loss", "fit_ms", "variables", "joint_angles_deg", "joints_3d"}
        return cls(
            seq=obj["seq"],
            t=float(t),
            ok=obj["ok"],
            reason=str(obj.get("reason", "")),
            loss=obj.get("loss"),
            fit_ms=obj.get("fit_ms"),
            variables=dict(obj.get("variables") or {}),
            joint_angles_deg=dict(obj.get("joint_angles_deg") or {}),
            joints_3d={k: tuple(v) for k, v in (obj.get("joints_3d") or {}).items()},
            extra={k: v for k, v in obj.items() if k not in known},
        )
