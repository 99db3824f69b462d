"""A world-frame stick body and a pinhole camera for scripted fall and daily-activity scenarios.

World frame: metres, x east, y north, z up; the floor is z = 0. The body's segment lengths follow Winter's
anthropometric table (fractions of body height H: hip joint 0.530 H, thigh 0.245 H, shank 0.246 H, ankle
0.039 H above the floor, shoulder 0.818 H, upper arm 0.186 H, forearm 0.146 H, foot 0.152 H). This is
deliberately not the fitter's humanoid model: the fit then meets a body it was not built from.

``StickPose`` holds the stick body's joint angles (degrees) and root (pelvis) orientation (not the fitter's
``fitting.kinematics.Pose``); ``place`` puts the body so that its lowest contact point rests on the floor or on a
seat/bed surface (a ``RestingPlace``); ``WorldCamera.project`` gives the 33x5 MediaPipe landmark array (pixels,
relative depth, visibility, presence) that a camera placed in the world sees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting import JOINT_3D_NAMES
from posed.landmarks import LANDMARK_NAMES


def rot_x(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@dataclass(frozen=True)
class StickPose:
    """The stick body's posture, degrees (the root's axes: see ``body_axes``).

    pitch: whole body tips forward (+) / backward (-) about the left-right axis; roll: tips to the body's
    left (+) / right (-); yaw: facing direction, degrees counter-clockwise from +y (north).
    Flexions are positive forward (hip, shoulder, trunk) and backward for the knee (Vicon-like).
    """

    yaw: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0
    trunk_flex: float = 0.0
    trunk_side: float = 0.0
    hip_flex_l: float = 0.0
    hip_flex_r: float = 0.0
    hip_abd_l: float = 0.0
    hip_abd_r: float = 0.0
    knee_l: float = 0.0
    knee_r: float = 0.0
    sh_flex_l: float = 0.0
    sh_flex_r: float = 0.0
    sh_abd_l: float = 8.0
    sh_abd_r: float = 8.0
    elbow_l: float = 10.0
    elbow_r: float = 10.0
    head_flex: float = 0.0
    ankle: float = 0.0              # plantarflexion (toes away from the shin), both feet

    def lerp(self, other: StickPose, w: float) -> StickPose:
        return StickPose(**{f.name: (1 - w) * getattr(self, f.name) + w * getattr(other, f.name) for f in fields(self)})

    def with_(self, **kw) -> StickPose:
        return replace(self, **kw)


@dataclass(frozen=True)
class RestingPlace:
    """Where the body rests in the world: ground position of the pelvis and the surface under the trunk (m)."""

    x: float = 0.0
    y: float = 0.0
    seat: float | None = None     # height of a chair/bed/sofa under the trunk; None = only the floor
    lift: float = 0.0             # extra height above the resting height (a jump, or the body mid-fall)


@dataclass(frozen=True)
class Body:
    height: float = 1.65

    def seg(self, frac: float) -> float:
        return frac * self.height


def body_axes(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Rotation of the pelvis: its columns are the body's right, forward and up axes in the world.

    Local frame (right-handed): x right, y forward, z up; at yaw 0 the body faces +y. In it, rot_x(-a)
    tips the up axis forward and rot_y(-a) tips it to the body's left.
    """
    return rot_z(yaw) @ rot_x(-pitch) @ rot_y(-roll)


# indices of our joint dictionary -> MediaPipe landmark numbers
MP = {name: i for i, name in enumerate(LANDMARK_NAMES)}
# contact spheres (point, radius as a fraction of H) used to rest the body on the floor
FLOOR_CONTACTS = (("left_heel", 0.012), ("right_heel", 0.012), ("left_foot_index", 0.012),
                  ("right_foot_index", 0.012), ("left_knee", 0.03), ("right_knee", 0.03), ("pelvis", 0.06),
                  ("chest", 0.065), ("head", 0.06), ("left_wrist", 0.02), ("right_wrist", 0.02),
                  ("left_elbow", 0.025), ("right_elbow", 0.025), ("left_hip", 0.055), ("right_hip", 0.055),
                  ("left_shoulder", 0.04), ("right_shoulder", 0.04), ("buttocks", 0.03))
SEAT_CONTACTS = (("pelvis", 0.06), ("buttocks", 0.03), ("chest", 0.065), ("left_hip", 0.055),
                 ("right_hip", 0.055), ("left_shoulder", 0.04), ("right_shoulder", 0.04), ("head", 0.06))


def skeleton(pose: StickPose, body: Body) -> dict[str, np.ndarray]:
    """Joint positions relative to the pelvis centre (world orientation, metres)."""
    H = body.height
    R = body_axes(pose.yaw, pose.pitch, pose.roll)
    left, fwd, up = -R[:, 0], R[:, 1], R[:, 2]
    j: dict[str, np.ndarray] = {"pelvis": np.zeros(3)}
    hip_half = 0.055 * H
    j["buttocks"] = -0.06 * H * up - 0.035 * H * fwd
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        s = side[0]
        flex, abd, knee = (getattr(pose, f"hip_flex_{s}"), getattr(pose, f"hip_abd_{s}"), getattr(pose, f"knee_{s}"))
        hip = sgn * hip_half * left
        # thigh: hang down, flex forward about the left axis, abduct outward about the forward axis
        r_thigh = R @ rot_x(flex) @ rot_y(sgn * abd)
        thigh_dir = r_thigh @ np.array([0.0, 0.0, -1.0])
        kneep = hip + 0.245 * H * thigh_dir
        r_shank = r_thigh @ rot_x(-knee)
        shank_dir = r_shank @ np.array([0.0, 0.0, -1.0])
        ankle = kneep + 0.246 * H * shank_dir
        r_foot = r_shank @ rot_x(-pose.ankle)
        foot_fwd = r_foot @ np.array([0.0, 1.0, 0.0])
        foot_down = r_foot @ np.array([0.0, 0.0, -1.0])
        j[f"{side}_hip"] = hip
        j[f"{side}_knee"] = kneep
        j[f"{side}_ankle"] = ankle
        j[f"{side}_heel"] = ankle + 0.025 * H * foot_down - 0.03 * H * foot_fwd
        j[f"{side}_foot_index"] = ankle + 0.025 * H * foot_down + 0.11 * H * foot_fwd
    r_trunk = R @ rot_x(-pose.trunk_flex) @ rot_y(-pose.trunk_side)
    t_left, t_fwd, t_up = -r_trunk[:, 0], r_trunk[:, 1], r_trunk[:, 2]
    neck = 0.288 * H * t_up
    j["chest"] = 0.17 * H * t_up - 0.02 * H * t_fwd
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        s = side[0]
        shoulder = neck + sgn * 0.11 * H * t_left
        r_arm = r_trunk @ rot_x(getattr(pose, f"sh_flex_{s}")) @ rot_y(sgn * getattr(pose, f"sh_abd_{s}"))
        elbow = shoulder + 0.186 * H * (r_arm @ np.array([0.0, 0.0, -1.0]))
        r_fore = r_arm @ rot_x(getattr(pose, f"elbow_{s}"))
        fore_dir = r_fore @ np.array([0.0, 0.0, -1.0])
        wrist = elbow + 0.146 * H * fore_dir
        j[f"{side}_shoulder"] = shoulder
        j[f"{side}_elbow"] = elbow
        j[f"{side}_wrist"] = wrist
        hand_side = r_fore @ np.array([-sgn, 0.0, 0.0])
        j[f"{side}_pinky"] = wrist + 0.05 * H * fore_dir + 0.012 * H * hand_side
        j[f"{side}_index"] = wrist + 0.055 * H * fore_dir - 0.008 * H * hand_side
        j[f"{side}_thumb"] = wrist + 0.03 * H * fore_dir - 0.02 * H * hand_side + 0.01 * H * (r_fore[:, 1])
    r_head = r_trunk @ rot_x(-pose.head_flex)
    h_left, h_fwd, h_up = -r_head[:, 0], r_head[:, 1], r_head[:, 2]
    head = neck + 0.075 * H * h_up
    j["head"] = head
    j["nose"] = head + 0.055 * H * h_fwd
    for side, sgn in (("left", 1.0), ("right", -1.0)):
        j[f"{side}_eye_inner"] = head + 0.048 * H * h_fwd + 0.012 * H * h_up + sgn * 0.01 * H * h_left
        j[f"{side}_eye"] = head + 0.045 * H * h_fwd + 0.012 * H * h_up + sgn * 0.02 * H * h_left
        j[f"{side}_eye_outer"] = head + 0.04 * H * h_fwd + 0.012 * H * h_up + sgn * 0.028 * H * h_left
        j[f"{side}_ear"] = head + 0.005 * H * h_fwd + 0.045 * H * sgn * h_left
        j[f"mouth_{side}"] = head + 0.045 * H * h_fwd - 0.025 * H * h_up + sgn * 0.014 * H * h_left
    return j


def rest_height(rel: dict[str, np.ndarray], body: Body, seat: float | None) -> float:
    """Pelvis height that puts the lowest contact on the floor, or the trunk on the seat when higher."""
    H = body.height
    z = max(r * H - rel[name][2] for name, r in FLOOR_CONTACTS)
    if seat is not None:
        z = max(z, max(seat + r * H - rel[name][2] for name, r in SEAT_CONTACTS))
    return z


def place(pose: StickPose, body: Body, where: RestingPlace) -> dict[str, np.ndarray]:
    """World joint positions (metres) of the posture resting at ``where``."""
    rel = skeleton(pose, body)
    z = rest_height(rel, body, where.seat) + where.lift
    origin = np.array([where.x, where.y, z])
    return {k: origin + v for k, v in rel.items()}


@dataclass(frozen=True)
class WorldCamera:
    """A pinhole camera placed in the world: at ``(x, y, z)`` (``z`` its height), looking along azimuth ``yaw``
    (deg from +y, counter-clockwise), pitched down by ``tilt`` (deg), rolled by ``roll`` (deg, as falls.features.gravity_from_tilt); a ``width`` x ``height`` image of
    horizontal field of view ``hfov`` (deg): its :attr:`intrinsics`."""

    x: float = 0.0
    y: float = 0.0
    z: float = 1.0
    yaw: float = 0.0
    tilt: float = 10.0
    roll: float = 0.0
    width: int = 640
    height: int = 480
    hfov: float = 69.0
    axes: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        a = math.radians(self.tilt)
        h = rot_z(self.yaw) @ np.array([0.0, 1.0, 0.0])      # horizontal forward
        right = rot_z(self.yaw) @ np.array([1.0, 0.0, 0.0])
        upw = np.array([0.0, 0.0, 1.0])
        z_c = math.cos(a) * h - math.sin(a) * upw
        y_c = -math.cos(a) * upw - math.sin(a) * h
        b = math.radians(self.roll)   # about the optical axis, as falls.features.gravity_from_tilt
        x_r = math.cos(b) * right + math.sin(b) * y_c
        y_r = -math.sin(b) * right + math.cos(b) * y_c
        object.__setattr__(self, "axes", np.stack([x_r, y_r, z_c]))

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics.from_hfov(self.hfov, self.width, self.height)

    @property
    def f(self) -> float:
        return self.intrinsics.fx

    def to_camera(self, p_world: np.ndarray) -> np.ndarray:
        return (np.asarray(p_world, float) - np.array([self.x, self.y, self.z])) @ self.axes.T

    def project(self, joints: dict[str, np.ndarray], body: Body, rng: np.random.Generator | None = None,
                noise_frac: float = 0.0) -> np.ndarray | None:
        """33x5 landmarks [x_px, y_px, z_rel, visibility, presence]; None when the body is behind the camera.

        ``noise_frac``: Gaussian 2D noise, sigma = that fraction of the body height in pixels at the
        pelvis's distance. Points outside the image get visibility 0.1 (as BlazePose reports them).
        """
        pts = np.array([self.to_camera(joints[name]) for name in MP])
        hip = self.to_camera(joints["pelvis"])
        if hip[2] <= 0.2 or np.any(pts[:, 2] <= 0.05):
            return None
        f = self.f
        u = f * pts[:, 0] / pts[:, 2] + self.width / 2.0
        v = f * pts[:, 1] / pts[:, 2] + self.height / 2.0
        if rng is not None and noise_frac > 0:
            sigma = noise_frac * body.height * f / hip[2]
            u = u + rng.normal(0.0, sigma, u.shape)
            v = v + rng.normal(0.0, sigma, v.shape)
        z_rel = (pts[:, 2] - hip[2]) * f / hip[2]
        inside = (u >= 0) & (u < self.width) & (v >= 0) & (v < self.height)
        vis = np.where(inside, 0.98, 0.1)
        return np.stack([u, v, z_rel, vis, np.where(inside, 0.99, 0.2)], axis=1)

    def joints_camera(self, joints: dict[str, np.ndarray]) -> dict[str, tuple[float, float, float]]:
        """The fit-result ``joints_3d`` of a perfect fit: camera axes, origin at the mid-hip (m)."""
        mid = self.to_camera(0.5 * (joints["left_hip"] + joints["right_hip"]))
        out = {"mid_hip": (0.0, 0.0, 0.0)}
        for n in JOINT_3D_NAMES[1:]:
            out[n] = tuple(float(v) for v in self.to_camera(joints[n]) - mid)
        return out
