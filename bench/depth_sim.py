"""What a RealSense D435-like stereo depth camera would measure at each landmark pixel (simulated).

At a landmark's pixel the camera sees the body's surface, not the joint centre: the measured point lies
``surface offset`` metres in front of the joint centre along the pixel's ray (``SURFACE_OFFSET_M``: about
the radius of the limb or torso there; face landmarks are on the skin already). The measurement then gets:

* Gaussian noise with RMS ``sigma_k * z**2`` (metres): the stereo depth RMS error grows with the square of the
  distance. Intel's D400-series papers (A. Grunnet-Jepsen et al., "Subpixel Linearity Improvement for Intel
  RealSense Depth Cameras", and Intel's D400 tuning guide) give RMS error = z^2 * subpixel / (f_px * baseline).
  D435: baseline 50 mm, 90 deg HFOV at 848 px -> f = 424 px; a subpixel RMS of 0.07 px (Intel quotes
  0.05-0.1 on textured targets) -> sigma_k = 0.07 / (424 * 0.050) = 0.0033 per metre: 3.0 cm at 3 m,
  8.3 cm at 5 m. The 0.07 is this benchmark's assumption, not a measurement.
* holes: a fraction ``hole_rate`` of the landmarks has no depth (NaN): stereo fails on untextured clothing
  and occlusion shadows.
* background hits at silhouette edges: a fraction ``background_rate`` of the landmarks (a landmark near the
  outline falls on the wall behind) measures ``background_behind_m`` (uniform range) behind the body.
* outside the image, nearer than ``min_range_m`` or farther than ``max_range_m``: NaN.

:func:`simulate_depth` returns 33 depths (metres along the optical axis, camera frame), NaN when unknown.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camera_model import Intrinsics
from landmarks import LANDMARK_NAMES

BASELINE_M = 0.050
FOCAL_D435_PX = 424.0      # 848 px at 90 deg horizontal field of view
SUBPIXEL_RMS = 0.07        # assumption (Intel: 0.05-0.1 px on a textured target)
SIGMA_K = SUBPIXEL_RMS / (FOCAL_D435_PX * BASELINE_M)   # 0.0033 / m


def _offsets() -> np.ndarray:
    off = np.zeros(len(LANDMARK_NAMES))
    for i, name in enumerate(LANDMARK_NAMES):
        if name.endswith(("shoulder", "hip")):
            off[i] = 0.10          # torso: shoulder and hip joint centres ~10 cm behind the front surface
        elif name.endswith(("elbow", "wrist", "knee", "ankle")):
            off[i] = 0.04          # limbs: ~4 cm radius
        elif name.endswith(("heel", "foot_index", "pinky", "index", "thumb")):
            off[i] = 0.02          # hands and feet
        else:
            off[i] = 0.0           # face landmarks are on the skin
    return off


SURFACE_OFFSET_M = _offsets()


@dataclass(frozen=True)
class DepthSim:
    """The simulator's parameters (metres)."""

    sigma_k: float = SIGMA_K              # RMS = sigma_k * z^2
    hole_rate: float = 0.03
    background_rate: float = 0.02
    background_behind_m: tuple[float, float] = (1.0, 3.0)
    min_range_m: float = 0.2
    max_range_m: float = 10.0

    def sigma(self, z_m: np.ndarray | float) -> np.ndarray | float:
        return self.sigma_k * np.asarray(z_m, float) ** 2


def simulate_depth(points_cam: np.ndarray, k: Intrinsics, rng: np.random.Generator,
                   sim: DepthSim | None = None) -> np.ndarray:
    """33 depths (m, along the optical axis) measured at the landmarks' pixels, NaN when unknown.

    ``points_cam``: (33, 3) joint centres and face points in the camera frame (m)."""
    sim = sim or DepthSim()
    p = np.asarray(points_cam, float)
    n = p.shape[0]
    rng_ = np.linalg.norm(p, axis=1)
    # the surface point: SURFACE_OFFSET_M nearer along the pixel's ray
    z = p[:, 2] * (1.0 - SURFACE_OFFSET_M[:n] / np.maximum(rng_, 1e-9))
    z = z + rng.normal(0.0, 1.0, n) * sim.sigma(z)
    u = rng.random(n)
    background = u < sim.background_rate
    hole = (u >= sim.background_rate) & (u < sim.background_rate + sim.hole_rate)
    lo, hi = sim.background_behind_m
    z = np.where(background, p[:, 2] + rng.uniform(lo, hi, n), z)
    uv = k.project(p)
    w, h = k.size
    outside = (uv[:, 0] < 0) | (uv[:, 0] >= w) | (uv[:, 1] < 0) | (uv[:, 1] >= h) | (p[:, 2] <= 0)
    z = np.where(hole | outside | (z < sim.min_range_m) | (z > sim.max_range_m), np.nan, z)
    return z
