"""Per-frame fall features from one fit result and its 2D landmarks.

Frames. Camera: x image right, y image down, z away from the camera (metres). The fit's ``joints_3d`` are
metric offsets from the mid-hip in the fit's frame: with a weak-perspective fit that frame looks along the
ray through the body (``fit_frame="ray"``), with a full-perspective fit it is the camera frame
(``fit_frame="camera"``). Gravity ``d_c`` is a unit vector pointing down, in camera coordinates.

Heights (metres above the floor): the mid-hip's camera-frame position ``P`` is the translation that makes the
fitted joints (metric offsets from the mid-hip, rotated into camera axes) project onto their 2D landmarks —
linear least squares in ``P`` (``locate``). With the floor a plane ``H`` below the camera along gravity,
``h_pelvis = H - P . d_c``; the other joints follow from their fitted offsets. A wrong body size scales ``P``
and every height below the camera in the same proportion, which is why the detector judges heights
relative to the person's own standing pelvis height.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting import BODY_LANDMARK_NAMES, BODY_LANDMARKS, FitResult

# joints_3d name -> MediaPipe landmark index
LANDMARK_INDEX = dict(zip(BODY_LANDMARK_NAMES, BODY_LANDMARKS, strict=True))
TORSO = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")
# Anthropometric ratios (Winter, Biomechanics and Motor Control of Human Movement, 4th ed., table 4.1):
# hip joint 0.530 H, knee 0.285 H, ankle 0.039 H above the floor; thigh 0.245 H, shank 0.246 H.
ANKLE_OVER_LEG = 0.039 / 0.491
PELVIS_OVER_LEG = 0.530 / 0.491
# Sitting on a chair: hips and knees flexed about 90 deg (a seat's height is about the lower leg's length); the
# trunk is then within about 20 deg of vertical (leaning back or forward in the chair)
SEATED_FLEX_DEG = (60.0, 120.0)


def gravity_from_tilt(tilt_deg: float, roll_deg: float = 0.0) -> np.ndarray:
    """Down, in camera coordinates, for a camera pitched down by ``tilt_deg`` and rolled clockwise (seen from
    behind the camera) by ``roll_deg``."""
    a, b = math.radians(tilt_deg), math.radians(roll_deg)
    return np.array([math.sin(b) * math.cos(a), math.cos(b) * math.cos(a), math.sin(a)])


def ray_rotation(ray: np.ndarray) -> np.ndarray:
    """Rotation R with R @ (0, 0, 1) = ray/|ray|, the smallest one (about an axis perpendicular to both)."""
    r = ray / np.linalg.norm(ray)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, r)
    s = float(np.linalg.norm(axis))
    c = float(r[2])
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * (kx @ kx)


@dataclass(frozen=True)
class FrameFeatures:
    """What one frame says about the body (metres above the floor, degrees, pixels)."""

    t: float
    below_camera_pelvis: float   # P . d_c: how far the mid-hip is below the camera along gravity
    below_camera_ankles: float | None   # the same for the mean visible ankle (None when not visible)
    offsets_down: dict[str, float]   # each joint's offset below the mid-hip along gravity (m)
    trunk_incl_deg: float        # mid-hip -> mid-shoulder against up; 0 upright, 90 horizontal
    leg_length: float            # fitted thigh + shank (m), mean of the two sides
    bbox_aspect: float           # width / height of the visible landmarks, roll-corrected
    flexion: dict[str, float]    # theta_hp_l/r, theta_kn_l/r (deg)
    upright_legs: bool           # hips and knees nearly straight (standing-reference candidate)
    unobserved: tuple[str, ...] = ()   # body landmarks not observed in this frame (fitted from the rest)
    body_up_c: np.ndarray | None = None    # mid-ankle -> mid-shoulder of the fit, unit, camera axes
    axis_plane_c: np.ndarray | None = None  # unit normal of the plane through the camera centre and the
                                            # image line mid-ankle -> mid-shoulder (normalized coordinates)
    straight_body: bool = False  # standing or walking: legs extended, trunk in line (whatever the gravity)
    ankles_c: np.ndarray | None = None   # the mean visible ankle's position, camera axes (m)
    seated_trunk_up_c: np.ndarray | None = None   # sitting (hips and knees flexed 60-120 deg): the trunk's
                                                  # mid-hip -> mid-shoulder direction, unit, camera axes
    below_camera_low_ankle: float | None = None   # the lower visible ankle's (a walking person's stance foot)
    low_ankle_c: np.ndarray | None = None         # its position, camera axes (m)


def locate(pixels: np.ndarray, offsets_c: np.ndarray, camera: Intrinsics) -> np.ndarray | None:
    """Camera-frame position T of the mid-hip from the joints' pixels and their fitted offsets (camera
    axes): least squares of the pinhole equations ``u - cx = fx (T + o)_x / (T + o)_z`` (linear in T)."""
    if len(pixels) < 3:
        return None
    du = pixels[:, 0] - camera.cx
    dv = pixels[:, 1] - camera.cy
    n = len(pixels)
    a = np.zeros((2 * n, 3))
    b = np.zeros(2 * n)
    a[:n, 0] = camera.fx
    a[:n, 2] = -du
    b[:n] = du * offsets_c[:, 2] - camera.fx * offsets_c[:, 0]
    a[n:, 1] = camera.fy
    a[n:, 2] = -dv
    b[n:] = dv * offsets_c[:, 2] - camera.fy * offsets_c[:, 1]
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    if not np.all(np.isfinite(sol)) or sol[2] <= 0.3:
        return None
    return sol


def _angle_deg(u: np.ndarray, v: np.ndarray, norm_u: float, norm_v: float) -> float:
    """The angle between ``u`` and ``v`` (their norms given, both above 0), degrees."""
    return math.degrees(math.acos(max(-1.0, min(1.0, float(u @ v) / (norm_u * norm_v)))))


def _trunk_thigh_deg(joints: dict[str, np.ndarray], trunk: np.ndarray, norm: float) -> list[float]:
    """Each hip's flexion as the angle between the trunk (mid-hip -> mid-shoulder, of length ``norm`` > 0) and
    the thigh (hip -> knee), from the fitted joint positions: 0 standing, 90 seated. Unlike the model's hip angle
    it does not depend on how the fit split the pelvis tilt between the lumbar spine and the hips (no landmark
    tells them apart)."""
    out = []
    for side in ("left", "right"):
        h, k = joints.get(f"{side}_hip"), joints.get(f"{side}_knee")
        if h is None or k is None:
            continue
        n_th = float(np.linalg.norm(k - h))
        if n_th >= 1e-9:
            out.append(180.0 - _angle_deg(trunk, k - h, norm, n_th))
    return out


def landmark_ok(landmarks: np.ndarray, index: int, min_vis: float, width: float, height: float) -> bool:
    row = landmarks[index]
    if not np.all(np.isfinite(row[:2])):
        return False
    vis = row[3] if landmarks.shape[1] > 3 and np.isfinite(row[3]) else 1.0
    pres = row[4] if landmarks.shape[1] > 4 and np.isfinite(row[4]) else 1.0
    return vis >= min_vis and pres >= min_vis and 0 <= row[0] < width and 0 <= row[1] < height


def measure(result: FitResult, landmarks: np.ndarray | None, image_size, camera: Intrinsics, d_c: np.ndarray,
            min_visibility: float, upright_knee_deg: float, roll_deg: float = 0.0,
            fit_frame: str = "ray", upright_trunk_deg: float = 20.0) -> FrameFeatures | None:
    """The frame's features, or None when it cannot be judged (no person, failed fit, torso not in view)."""
    if not result.ok or landmarks is None or not result.joints_3d:
        return None
    lm = np.asarray(landmarks, float)
    if lm.ndim != 2 or lm.shape[0] < 29 or lm.shape[1] < 2:
        return None
    width, height = float(image_size[0]), float(image_size[1])
    joints = {k: np.asarray(v, float) for k, v in result.joints_3d.items()}
    if any(name not in joints for name in TORSO):
        return None
    visible = {name: landmark_ok(lm, i, min_visibility, width, height) for name, i in LANDMARK_INDEX.items()}
    # a partial body is judged: three of the four torso landmarks (a shoulder or hip off the image, a person
    # falling towards the camera) locate the body; the fit places the unobserved one
    if sum(visible[name] for name in TORSO) < 3:
        return None
    names = [n for n, ok in visible.items() if ok and n in joints and np.all(np.isfinite(joints[n]))]
    hips_seen = [lm[LANDMARK_INDEX[n], :2] for n in ("left_hip", "right_hip") if visible[n]]
    hip_px = np.mean(hips_seen, axis=0) if hips_seen else 0.5 * (lm[23, :2] + lm[24, :2])
    ray = np.array([(hip_px[0] - camera.cx) / camera.fx, (hip_px[1] - camera.cy) / camera.fy, 1.0])
    r_fit = ray_rotation(ray) if fit_frame == "ray" else np.eye(3)
    mid_hip = joints.get("mid_hip", 0.5 * (joints["left_hip"] + joints["right_hip"]))
    pelvis = locate(np.array([lm[LANDMARK_INDEX[n], :2] for n in names]),
                    np.array([joints[n] - mid_hip for n in names]) @ r_fit.T, camera)
    if pelvis is None:
        return None
    d_fit = r_fit.T @ d_c
    offsets = {n: float((v - mid_hip) @ d_fit) for n, v in joints.items()}
    trunk = 0.5 * (joints["left_shoulder"] + joints["right_shoulder"]) - mid_hip
    norm = float(np.linalg.norm(trunk))
    if norm < 1e-6:
        return None
    incl = math.degrees(math.acos(max(-1.0, min(1.0, float(-trunk @ d_fit) / norm))))
    legs = []
    for side in ("left", "right"):
        h, k, a = (joints.get(f"{side}_{j}") for j in ("hip", "knee", "ankle"))
        if h is not None and k is not None and a is not None:
            legs.append(float(np.linalg.norm(k - h) + np.linalg.norm(a - k)))
    leg = float(np.mean(legs)) if legs else 0.8
    ankles = [n for n in ("left_ankle", "right_ankle") if visible.get(n) and n in joints]
    below_ankles = float(pelvis @ d_c + np.mean([offsets[n] for n in ankles])) if ankles else None
    low = max(ankles, key=lambda n: offsets[n]) if ankles else None
    below_low_ankle = float(pelvis @ d_c + offsets[low]) if low else None
    low_ankle_c = pelvis + r_fit @ (joints[low] - mid_hip) if low else None
    ankles_c = pelvis + r_fit @ np.mean([joints[n] - mid_hip for n in ankles], axis=0) if ankles else None
    pts = np.array([lm[LANDMARK_INDEX[n], :2] for n, ok in visible.items() if ok])
    if roll_deg:
        b = math.radians(roll_deg)
        rot = np.array([[math.cos(b), math.sin(b)], [-math.sin(b), math.cos(b)]])
        pts = pts @ rot.T
    extent = pts.max(0) - pts.min(0)
    aspect = float(extent[0] / max(extent[1], 1e-6))
    ja = result.joint_angles_deg
    flex = {k: float(ja[k]) for k in ("theta_hp_l", "theta_hp_r", "theta_kn_l", "theta_kn_r") if k in ja}
    upright_legs = bool(flex) and all(abs(v) < upright_knee_deg for v in flex.values())
    body_up = axis_plane = None
    straight = False
    if all(n in joints for n in ("left_ankle", "right_ankle")):
        ankle_mid = 0.5 * (joints["left_ankle"] + joints["right_ankle"])
        up_fit = 0.5 * (joints["left_shoulder"] + joints["right_shoulder"]) - ankle_mid
        n_up = float(np.linalg.norm(up_fit))
        leg_axis = mid_hip - ankle_mid
        n_leg = float(np.linalg.norm(leg_axis))
        if n_up > 1e-6 and n_leg > 1e-6:
            body_up = r_fit @ (up_fit / n_up)
            # standing or walking, whatever the gravity: the trunk in line with the hips-to-ankles axis and
            # both legs nearly extended (hip-ankle at least 85 % of thigh + shank: not sitting, squatting or
            # kneeling); walking's bent swing knee keeps its ankle under the body
            bend = _angle_deg(trunk, leg_axis, norm, n_leg)
            extended = all(
                np.linalg.norm(joints[f"{sd}_ankle"] - joints[f"{sd}_hip"])
                >= 0.85 * (np.linalg.norm(joints[f"{sd}_knee"] - joints[f"{sd}_hip"])
                           + np.linalg.norm(joints[f"{sd}_ankle"] - joints[f"{sd}_knee"]))
                for sd in ("left", "right") if f"{sd}_knee" in joints and f"{sd}_hip" in joints)
            straight = extended and bend < upright_trunk_deg
        seen = ("left_shoulder", "right_shoulder", "left_ankle", "right_ankle")
        if all(visible[n] for n in seen):
            top = 0.5 * (lm[11, :2] + lm[12, :2])
            bottom = 0.5 * (lm[23, :2] + lm[24, :2])
            a = np.array([(bottom[0] - camera.cx) / camera.fx, (bottom[1] - camera.cy) / camera.fy, 1.0])
            b = np.array([(top[0] - camera.cx) / camera.fx, (top[1] - camera.cy) / camera.fy, 1.0])
            normal = np.cross(a, b)
            n_norm = float(np.linalg.norm(normal))
            if n_norm > 1e-9:
                axis_plane = normal / n_norm
    seated = None
    hips = _trunk_thigh_deg(joints, trunk, norm)
    if len(flex) == 4 and len(hips) == 2 and all(
            SEATED_FLEX_DEG[0] <= abs(v) <= SEATED_FLEX_DEG[1] for v in (*hips, flex["theta_kn_l"], flex["theta_kn_r"])):
        seated = r_fit @ (trunk / norm)
    unobserved = tuple(n for n, ok in visible.items() if not ok)
    return FrameFeatures(seated_trunk_up_c=seated, ankles_c=ankles_c, t=result.t, below_camera_pelvis=float(pelvis @ d_c), below_camera_ankles=below_ankles,
                         offsets_down=offsets, trunk_incl_deg=incl, leg_length=leg, bbox_aspect=aspect, flexion=flex,
                         upright_legs=upright_legs, unobserved=unobserved, body_up_c=body_up,
                         axis_plane_c=axis_plane, straight_body=straight, below_camera_low_ankle=below_low_ankle,
                         low_ankle_c=low_ankle_c)
