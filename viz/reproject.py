"""The fitted skeleton in image pixels, through the fit's own camera model (so a wrong depth or a lag shows).

Perspective fit (the recording's or the camera's intrinsics were known; the result has ``root_cam_m``): each
joint in the camera frame is ``root_cam_m + joints_3d[name]`` (metres, x image right, y image down, z away
from the camera) and projects through the pinhole ``Intrinsics.project`` — nothing is adjusted to the
landmarks, so a wrong depth, size or timing of the fit is visible as a mismatch with them.

A fit without ``root_cam_m`` (through an assumed lens, the source knowing no intrinsics, or orthographic,
the paper's model): the result carries no image position or scale, so the
scale and offset that best place the model's x, y on the frame's landmarks (least squares over the fitted
landmarks) are solved here; a depth error then stays invisible, a wrong pose or a lag still shows.
``Reprojection.how`` says which was used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics

# BlazePose index of each fitted body joint (fitting.BODY_LANDMARK_NAMES order)
LANDMARK_INDEX = {
    "left_shoulder": 11, "right_shoulder": 12, "left_elbow": 13, "right_elbow": 14, "left_wrist": 15,
    "right_wrist": 16, "left_hip": 23, "right_hip": 24, "left_knee": 25, "right_knee": 26, "left_ankle": 27,
    "right_ankle": 28,
}


@dataclass(frozen=True)
class Reprojection:
    """Pixels (x right, y down) of each fitted joint; ``how``: ``perspective`` or ``laid on the landmarks
    (scale and offset; the fit has no position)``: what the overlay's bottom line says."""

    pixels: dict[str, tuple[float, float]]
    how: str


def camera_joints(joints_3d: dict, root_cam_m) -> dict[str, np.ndarray]:
    """Joints in the camera frame (metres): the mid-hip-relative ``joints_3d`` moved to ``root_cam_m``."""
    root = np.asarray(root_cam_m, float)
    return {k: root + np.asarray(v, float) for k, v in joints_3d.items()}


def reproject(joints_3d: dict, root_cam_m, intrinsics: Intrinsics | None,
              landmarks: np.ndarray | None) -> Reprojection | None:
    """The fitted joints in pixels, or None when there is no way to place them (orthographic without
    landmarks, or fewer than two usable landmarks)."""
    if not joints_3d:
        return None
    if root_cam_m is not None and intrinsics is not None:
        cam = camera_joints(joints_3d, root_cam_m)
        names = list(cam)
        pts = np.array([cam[n] for n in names])
        if np.all(pts[:, 2] > 1e-3):
            uv = intrinsics.project(pts)
            return Reprojection({n: (float(u), float(v)) for n, (u, v) in zip(names, uv, strict=True)},
                                "perspective")
    if landmarks is None:
        return None
    lm = np.asarray(landmarks, float)
    src, dst = [], []
    for name, idx in LANDMARK_INDEX.items():
        if name in joints_3d and np.all(np.isfinite(lm[idx, :2])) and (lm.shape[1] < 4 or lm[idx, 3] >= 0.3):
            src.append(joints_3d[name][:2])
            dst.append(lm[idx, :2])
    if len(src) < 2:
        return None
    src_a, dst_a = np.array(src, float), np.array(dst, float)
    sc, dc = src_a.mean(0), dst_a.mean(0)
    s_var = float(((src_a - sc) ** 2).sum())
    if s_var <= 0:
        return None
    k = float(((src_a - sc) * (dst_a - dc)).sum() / s_var)   # scale only: no rotation, the camera is level
    pixels = {n: (float(dc[0] + k * (v[0] - sc[0])), float(dc[1] + k * (v[1] - sc[1])))
              for n, v in joints_3d.items()}
    # not "orthographic": the fit itself may be perspective through an assumed lens; only its placement is solved
    return Reprojection(pixels, "laid on the landmarks (scale and offset; the fit has no position)")
