"""Forward kinematics of the humanoid model in plain NumPy: the reference the numba kernels are tested
against, and what the simulator renders.

Frames (docs/body-model.md has the drawing):

* pelvis (body) frame B, origin at the mid-hip (the lumbar joint, the model's root): x forward (anterior),
  y to the person's left, z up. With every angle zero the person stands upright, arms and legs straight down.
* camera frame C (interfaces.md): x image right, y image down, z away from the camera; metres, origin at the
  mid-hip. The camera is assumed level, so gravity is +y of C. With the three body angles zero the person
  faces the camera: B->C maps x_B -> -z_C, y_B -> +x_C, z_B -> -y_C.

Rotations (Vicon Plug-in Gait polarity, Cardan order flexion -> ab/adduction -> rotation):

* body:  R_CB = R0 Rz(psi_bd) Rx(-phi_bd) Ry(theta_bd): theta_bd > 0 forward tilt, phi_bd > 0 tilt to
  the left, psi_bd > 0 turn to the left (paper section 2.3).
* lumbar: Ry(theta_tr) Rx(-phi_tr) Rz(psi_tr): flexion (forward bend), lateral bend to the left, twist to
  the left positive.
* hip:   Ry(-theta_hp) Rx(-s phi_hp) Rz(-s psi_hp), s = +1 left, -1 right: flexion, adduction, internal
  rotation positive on both sides. knee: Ry(+theta_kn) flexion positive.
* ankle: Ry(-theta_an) Rx(-s phi_an): dorsiflexion, inversion positive.
* shoulder: Ry(-theta_sh) Rx(-s phi_sh) Rz(-s psi_sh): flexion, adduction, internal rotation positive (the
  rotation is not among the paper's 23 angles: the fit searches it only with BlazePose's world landmarks,
  else holds it at 0). elbow: Ry(-theta_el) flexion positive.
* head:  Ry(theta_hd) Rz(psi_hd): nod forward, turn left positive.

Because the body pitch theta_bd is the innermost body rotation and the lumbar and hip flexions are the
outermost rotations of their chains, (theta_bd + d, theta_tr - d, theta_hp_l + d, theta_hp_r + d) leaves
every landmark, the centre of mass and the feet where they were: the pelvis tilt is not observable.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from posed.fitting.body import SEGMENT_MASS, BodyDimensions
from posed.fitting.result import (
    BODY_ANGLE_NAMES,
    JOINT_3D_NAMES,
    JOINT_ANGLE_NAMES,
    SHOULDER_ROTATION_NAMES,
    VARIABLE_NAMES,
)

# Camera axes of the pelvis axes in the neutral pose (columns: x_B, y_B, z_B in C).
R0 = np.array([[0.0, 1.0, 0.0],
               [0.0, 0.0, -1.0],
               [-1.0, 0.0, 0.0]])

# MediaPipe indices of the 12 body landmarks the fit uses (paper section 2.1), in this order everywhere.
BODY_LANDMARKS = (11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)
BODY_LANDMARK_NAMES = JOINT_3D_NAMES[1:]

# Points of the head, hands and feet that the fit does not use, as fractions of body height in the head,
# forearm and foot frames (x forward, y left, z up in the neutral pose); plausible, not measured.
_HEAD_POINTS = {  # relative to the mid-shoulder (the neck joint)
    0: (0.060, 0.0, 0.095),                                        # nose
    1: (0.055, 0.012, 0.118), 2: (0.052, 0.022, 0.118), 3: (0.047, 0.032, 0.118),    # left eye
    4: (0.055, -0.012, 0.118), 5: (0.052, -0.022, 0.118), 6: (0.047, -0.032, 0.118),  # right eye
    7: (0.0, 0.047, 0.112), 8: (0.0, -0.047, 0.112),              # ears (head centre of mass: their middle)
    9: (0.055, 0.016, 0.078), 10: (0.055, -0.016, 0.078),          # mouth
}
_HAND_POINTS = {"pinky": (-0.015, 0.0, -0.075), "index": (0.012, 0.0, -0.085), "thumb": (0.025, 0.0, -0.050)}
_EAR_HEIGHT = 0.112


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def body_rotation(theta_bd: float, phi_bd: float, psi_bd: float) -> np.ndarray:
    """R_CB (camera from pelvis frame) for body angles in degrees."""
    t, p, s = (math.radians(a) for a in (theta_bd, phi_bd, psi_bd))
    return R0 @ rot_z(s) @ rot_x(-p) @ rot_y(t)


def body_angles_from_rotation(r_cb: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`body_rotation` (degrees; phi in [-90, 90]; at phi = +-90 theta is set to 0)."""
    m = R0.T @ np.asarray(r_cb, dtype=np.float64)  # = Rz(psi) Rx(-phi) Ry(theta)
    # Rz(s) Rx(q) Ry(t), q = -phi: m[2,1] = sin q; m[0,1] = -sin s cos q; m[1,1] = cos s cos q;
    # m[2,0] = -cos q sin t; m[2,2] = cos q cos t.
    sq = max(-1.0, min(1.0, m[2, 1]))
    q = math.asin(sq)
    if abs(math.cos(q)) < 1e-9:
        t = 0.0
        # Rz(s) Rx(+-90): m[0,0] = cos s, m[1,0] = sin s
        s = math.atan2(m[1, 0], m[0, 0])
    else:
        s = math.atan2(-m[0, 1], m[1, 1])
        t = math.atan2(-m[2, 0], m[2, 2])
    return math.degrees(t), -math.degrees(q), math.degrees(s)


@dataclass(frozen=True)
class Pose:
    """A pose of the model: the 23 joint angles, the 3 body angles and the upper arms' rotations, degrees
    (Vicon polarity).

    Missing joint angles are 0. ``joints`` is stored as a plain dict with every name of JOINT_ANGLE_NAMES.
    """

    joints: Mapping[str, float] = field(default_factory=dict)
    theta_bd: float = 0.0
    phi_bd: float = 0.0
    psi_bd: float = 0.0
    psi_sh_l: float = 0.0
    psi_sh_r: float = 0.0

    def __post_init__(self) -> None:
        unknown = set(self.joints) - set(JOINT_ANGLE_NAMES)
        if unknown:
            raise ValueError(f"unknown joint angle name(s): {sorted(unknown)}; valid: {JOINT_ANGLE_NAMES}")
        full = {name: float(self.joints.get(name, 0.0)) for name in JOINT_ANGLE_NAMES}
        object.__setattr__(self, "joints", full)

    def angle(self, name: str) -> float:
        if name in BODY_ANGLE_NAMES or name in SHOULDER_ROTATION_NAMES:
            return float(getattr(self, name))
        return self.joints[name]

    def replace(self, **angles: float) -> Pose:
        """A copy with some joint or body angles replaced (degrees)."""
        joints = dict(self.joints)
        body = {k: getattr(self, k) for k in BODY_ANGLE_NAMES + SHOULDER_ROTATION_NAMES}
        for k, v in angles.items():
            if k in body:
                body[k] = float(v)
            elif k in JOINT_ANGLE_NAMES:
                joints[k] = float(v)
            else:
                raise ValueError(f"unknown angle {k!r}")
        return Pose(joints, **body)

    def variables(self, gamma: float = 1.0) -> dict[str, float]:
        """The 19 optimization variables of eq. (6) (degrees; gamma as given)."""
        out = {"gamma": float(gamma)}
        for name in VARIABLE_NAMES[1:]:
            out[name] = self.angle(name)
        return out


def _r(deg: float) -> float:
    return math.radians(deg)


@dataclass(frozen=True)
class Skeleton:
    """Forward kinematics result in the pelvis frame B (metres)."""

    landmarks: np.ndarray          # (33, 3) MediaPipe order
    com: np.ndarray                # (3,) whole-body centre of mass


def skeleton(pose: Pose, dims: BodyDimensions) -> Skeleton:
    """Every landmark and the centre of mass of ``pose`` in the pelvis frame."""
    j = pose.joints
    h = dims.body_height_m
    pts = np.zeros((33, 3))
    seg: dict[str, tuple[np.ndarray, float]] = {}  # segment -> (centre of mass, mass fraction)

    r_tr = rot_y(_r(j["theta_tr"])) @ rot_x(-_r(j["phi_tr"])) @ rot_z(_r(j["psi_tr"]))
    mid_sh = r_tr @ np.array([0.0, 0.0, dims.trunk_m])
    seg["trunk"] = (0.5 * mid_sh, SEGMENT_MASS["trunk"][0])

    r_hd = r_tr @ rot_y(_r(j["theta_hd"])) @ rot_z(_r(j["psi_hd"]))
    for idx, off in _HEAD_POINTS.items():
        pts[idx] = mid_sh + r_hd @ (np.array(off) * h)
    seg["head"] = (mid_sh + r_hd @ np.array([0.0, 0.0, _EAR_HEIGHT * h]), SEGMENT_MASS["head"][0])

    for side, s, i_sh, i_el, i_wr, i_pk, i_ix, i_th in (("l", 1.0, 11, 13, 15, 17, 19, 21),
                                                        ("r", -1.0, 12, 14, 16, 18, 20, 22)):
        sh = r_tr @ np.array([0.0, s * dims.shoulder_half_m, dims.trunk_m])
        r_ua = (r_tr @ rot_y(-_r(j[f"theta_sh_{side}"])) @ rot_x(-s * _r(j[f"phi_sh_{side}"]))
                @ rot_z(-s * _r(pose.angle(f"psi_sh_{side}"))))
        el = sh + r_ua @ np.array([0.0, 0.0, -dims.upper_arm_m])
        r_fa = r_ua @ rot_y(-_r(j[f"theta_el_{side}"]))
        wr = el + r_fa @ np.array([0.0, 0.0, -dims.forearm_m])
        pts[i_sh], pts[i_el], pts[i_wr] = sh, el, wr
        for idx, key in ((i_pk, "pinky"), (i_ix, "index"), (i_th, "thumb")):
            pts[idx] = wr + r_fa @ (np.array(_HAND_POINTS[key]) * h)
        m_ua, c_ua = SEGMENT_MASS["upper_arm"]
        m_fa, c_fa = SEGMENT_MASS["forearm"]
        m_hn, c_hn = SEGMENT_MASS["hand"]
        seg[f"upper_arm_{side}"] = (sh + c_ua * (el - sh), m_ua)
        seg[f"forearm_{side}"] = (el + c_fa * (wr - el), m_fa)
        seg[f"hand_{side}"] = (wr + r_fa @ np.array([0.0, 0.0, -c_hn * 0.5 * dims.hand_m]), m_hn)

    for side, s, i_hp, i_kn, i_an, i_he, i_ft in (("l", 1.0, 23, 25, 27, 29, 31), ("r", -1.0, 24, 26, 28, 30, 32)):
        hp = np.array([0.0, s * dims.hip_half_m, 0.0])
        r_th = rot_y(-_r(j[f"theta_hp_{side}"])) @ rot_x(-s * _r(j[f"phi_hp_{side}"])) @ rot_z(
            -s * _r(j[f"psi_hp_{side}"]))
        kn = hp + r_th @ np.array([0.0, 0.0, -dims.thigh_m])
        r_sk = r_th @ rot_y(_r(j[f"theta_kn_{side}"]))
        an = kn + r_sk @ np.array([0.0, 0.0, -dims.shank_m])
        r_ft = r_sk @ rot_y(-_r(j[f"theta_an_{side}"])) @ rot_x(-s * _r(j[f"phi_an_{side}"]))
        heel = an + r_ft @ np.array([-0.25 * dims.foot_length_m, 0.0, -dims.ankle_height_m])
        toe = an + r_ft @ np.array([0.75 * dims.foot_length_m, 0.0, -dims.ankle_height_m])
        pts[i_hp], pts[i_kn], pts[i_an], pts[i_he], pts[i_ft] = hp, kn, an, heel, toe
        m_th, c_th = SEGMENT_MASS["thigh"]
        m_sk, c_sk = SEGMENT_MASS["shank"]
        m_ft, _ = SEGMENT_MASS["foot"]
        seg[f"thigh_{side}"] = (hp + c_th * (kn - hp), m_th)
        seg[f"shank_{side}"] = (kn + c_sk * (an - kn), m_sk)
        seg[f"foot_{side}"] = (an + r_ft @ foot_com_offset(dims), m_ft)

    total = sum(m for _, m in seg.values())
    com = sum(p * m for p, m in seg.values()) / total
    return Skeleton(pts, com)


def foot_com_offset(dims: BodyDimensions) -> np.ndarray:
    """Foot centre of mass in the foot frame: halfway from the ankle to the ball of the foot (the head of
    metatarsal II, taken at 70 % of the foot length from the heel, on the sole), Winter Table 4.1."""
    return np.array([0.225 * dims.foot_length_m, 0.0, -0.5 * dims.ankle_height_m])


def to_camera(points_b: np.ndarray, pose: Pose) -> np.ndarray:
    """Pelvis-frame points (..., 3) -> camera axes (metres, origin mid-hip)."""
    r = body_rotation(pose.theta_bd, pose.phi_bd, pose.psi_bd)
    return np.asarray(points_b) @ r.T


def landmarks_camera(pose: Pose, dims: BodyDimensions) -> np.ndarray:
    """(33, 3) landmarks in camera axes, metres, origin at the mid-hip."""
    return to_camera(skeleton(pose, dims).landmarks, pose)


def joints_3d(pose: Pose, dims: BodyDimensions) -> dict[str, tuple[float, float, float]]:
    """interfaces.md ``joints_3d``: mid_hip and the 12 body landmarks, camera axes, metres."""
    cam = landmarks_camera(pose, dims)
    out = {"mid_hip": (0.0, 0.0, 0.0)}
    for name, idx in zip(BODY_LANDMARK_NAMES, BODY_LANDMARKS, strict=True):
        out[name] = tuple(float(v) for v in cam[idx])
    return out
