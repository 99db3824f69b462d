"""The fit result of one frame (interfaces.md section 2): what ``posed fit`` writes and Zenoh carries."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from posed.fitting.measured import Measured

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

# The upper arms' rotation about their own axis (internal rotation positive), degrees: not among the paper's 23
# angles (its shoulder is flexion and adduction only); with fitting.shoulder_rotation on, the fit searches them
# when BlazePose's world landmarks tell the arms' depth, and then reports them as ``shoulder_rotation_deg``.
SHOULDER_ROTATION_NAMES = ("psi_sh_l", "psi_sh_r")
# The kernels' solution vector x (fitting.layout X_*): the paper's 19, then the upper arms' rotations.
MODEL_VARIABLE_NAMES = VARIABLE_NAMES + SHOULDER_ROTATION_NAMES

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

    ``measured`` (fitting.measured): which landmarks, angles and joints this frame measured; every value
    not listed there is the model's guess, never to be shown as a fact. Given by the fit; a result built or
    read without it gets it from the same rule applied to ``extra.missing`` (nothing when not ``ok``).
    ``angle(name)``, ``measured_angles()`` and ``measured_joints()`` return only measured values.
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
    measured: Measured | None = None

    def __post_init__(self) -> None:
        if self.measured is None:
            from posed.fitting.measured import Measured

            object.__setattr__(self, "measured", Measured.of_legacy(self.extra) if self.ok else Measured())

    def angle(self, name: str) -> float | None:
        """Degrees of one angle on this frame, by its plain name (``left knee flexion``, fitting.angle_names)
        or its symbol (``theta_kn_l``); None when this frame did not measure it (fitting.measured). Raises
        KeyError, listing the names, for an unknown one."""
        from posed.fitting.angle_names import symbol

        sym = symbol(name)
        if not self.ok or sym not in self.measured.angles:
            return None
        v = self.joint_angles_deg.get(sym, self.variables.get(sym))
        return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None

    def measured_angles(self, plain: bool = False) -> dict[str, float]:
        """The joint angles and body angles this frame measured, degrees, by symbol (``plain``: by plain
        name); the rest are left out."""
        from posed.fitting.angle_names import PLAIN_NAMES

        out = {}
        for sym in self.measured.angles if self.ok else ():
            v = self.joint_angles_deg.get(sym, self.variables.get(sym))
            if isinstance(v, (int, float)) and math.isfinite(v):
                out[PLAIN_NAMES[sym] if plain else sym] = float(v)
        return out

    def measured_joints(self) -> dict[str, tuple[float, float, float]]:
        """The ``joints_3d`` whose landmarks this frame measured (metres, mid-hip origin); the rest left out."""
        return {k: v for k, v in self.joints_3d.items() if k in self.measured.joints} if self.ok else {}

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
        if self.ok:
            out["measured"] = self.measured.to_json()
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
        known = {"seq", "t", "ok", "reason", "loss", "fit_ms", "variables", "joint_angles_deg", "joints_3d",
                 "measured"}
        measured = None
        if obj.get("measured") is not None:
            from posed.fitting.measured import Measured

            measured = Measured.from_json(obj["measured"])
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
            measured=measured,
        )
