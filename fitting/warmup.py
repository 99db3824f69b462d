"""The frames :meth:`fitting.fitter.Fitter.warmup` fits to compile (or load from the numba cache) every kernel
before the daemon reports READY: a standing person with arms raised to the front, body yaw 30 degrees, seen by
a level orthographic camera (image x right, y down; a standing body spans 60 % of the image height), exact
and with Gaussian pixel noise from an explicit seed. Only the code paths matter, not the pose."""

from __future__ import annotations

import numpy as np

from posed.fitting.body import BodyDimensions
from posed.fitting.kinematics import Pose, landmarks_camera

IMAGE_SIZE = (640, 480)
POSE = Pose({"theta_sh_l": 90.0, "theta_sh_r": 85.0, "phi_sh_l": -5.0, "phi_sh_r": -3.0, "theta_el_l": 10.0,
             "theta_el_r": 5.0, "theta_tr": 3.0, "theta_kn_l": 3.0, "theta_kn_r": 2.0}, psi_bd=30.0)


def warmup_landmarks(dims: BodyDimensions, noise_px: float = 0.0, seed: int = 1) -> np.ndarray:
    """(33, 5) ``[x_px, y_px, z, visibility, presence]`` of :data:`POSE` in a 640x480 image."""
    w, h = IMAGE_SIZE
    s = 0.6 * h / dims.body_height_m                     # pixels per metre
    pts = landmarks_camera(POSE, dims)                   # camera axes, metres, mid-hip origin
    xy = np.array([w / 2.0, h / 2.0]) + s * pts[:, :2]
    if noise_px > 0:
        xy = xy + np.random.default_rng(seed).normal(0.0, noise_px, size=xy.shape)
    vis = np.full(33, 0.99)
    return np.column_stack([xy, s * pts[:, 2], vis, vis])


def warmup_depth(dims: BodyDimensions, distance_m: float = 3.0) -> np.ndarray:
    """(33,) metres: what an aligned depth camera would measure at the landmarks of :data:`POSE` with its
    mid-hip ``distance_m`` away (the joint centres themselves; for the depth kernels' code paths)."""
    return distance_m + landmarks_camera(POSE, dims)[:, 2]
