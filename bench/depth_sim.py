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
* self-occlusion (``self_occlusion``): the body is a set of capsules (:data:`CAPSULES`: the torso, the head,
  each limb segment, with the radii of the surface offsets); where a landmark's pixel ray enters another part
  of the body before the landmark's own surface, the camera measures that part instead: the far shoulder and
  hip seen from the side (the torso in front), a hand in front of the chest, the far leg behind the near one.

:func:`simulate_depth` returns 33 depths (metres along the optical axis, camera frame), NaN when unknown.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.landmarks import LANDMARK_NAMES

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

TORSO_RADIUS_M = 0.10   # as the torso's surface offset: about 20 cm deep
LIMB_RADIUS_M = 0.04    # as the limbs' surface offset
HEAD_RADIUS_M = 0.08
_SIDES = ("left", "right")
# (end a, end b, radius m), each end the mean of the landmarks named (a name may repeat: a weighted mean): the
# torso as the shoulder line, the hip line and three upright capsules side by side (mid-shoulder to mid-hip, and
# on each side from halfway between the shoulder and the mid-shoulder down to the hip: 17-19 cm half-width with
# the radius, about an adult's waist and hips; a hanging arm stays outside), the head (ear to ear), every limb
# segment
_ONE_SIDE = {s: (f"{s}_shoulder",) * 3 + (f"{o}_shoulder",) for s, o in zip(_SIDES, _SIDES[::-1], strict=True)}
CAPSULES = (
    (("left_shoulder",), ("right_shoulder",), TORSO_RADIUS_M),
    (("left_hip",), ("right_hip",), TORSO_RADIUS_M),
    (("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"), TORSO_RADIUS_M),
    *((_ONE_SIDE[s], (f"{s}_hip",), TORSO_RADIUS_M) for s in _SIDES),
    (("left_ear",), ("right_ear",), HEAD_RADIUS_M),
    *(((f"{s}_{a}",), (f"{s}_{b}",), LIMB_RADIUS_M) for s in _SIDES
      for a, b in (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle"))),
)


def _capsule_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CAPSULES as averaging matrices over the 33 landmarks (ends a and b, each (C, 33)) and radii (C,)."""
    idx = {n: i for i, n in enumerate(LANDMARK_NAMES)}
    ends = np.zeros((2, len(CAPSULES), len(LANDMARK_NAMES)))
    for c, (a, b, _) in enumerate(CAPSULES):
        for e, names in enumerate((a, b)):
            for n in names:
                ends[e, c, idx[n]] += 1.0 / len(names)
    return ends[0], ends[1], np.array([r for _, _, r in CAPSULES])


_CAP_A, _CAP_B, _CAP_R = _capsule_arrays()


def first_body_hit(points_cam: np.ndarray) -> np.ndarray:
    """For each of the 33 landmarks, the depth (m, camera z) at which its pixel's ray first enters one of the
    body's capsules (CAPSULES, around the segments between ``points_cam``, (33, 3), camera frame), inf if it
    enters none. The entry is that of the sphere of the capsule's radius around the segment's point nearest the
    ray (exact for a segment across the ray, a little behind the true entry for an oblique one)."""
    p = np.asarray(points_cam, float)
    d = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-9)      # (N, 3) unit rays
    a, u = _CAP_A @ p, (_CAP_B - _CAP_A) @ p                              # (C, 3) capsule start, axis
    ad, ud = d @ a.T, d @ u.T                                           # (N, C)
    uu, au = np.sum(u * u, axis=1), np.sum(a * u, axis=1)                # (C,)
    den = uu[None, :] - ud ** 2
    s = np.where(den > 1e-12, -(au[None, :] - ad * ud) / np.maximum(den, 1e-12), 0.0)
    s = np.clip(s, 0.0, 1.0)                                            # nearest point of each segment
    q = a[None, :, :] + s[:, :, None] * u[None, :, :]                   # (N, C, 3)
    t = np.sum(q * d[:, None, :], axis=2)                               # along the ray
    miss2 = np.sum(q * q, axis=2) - t ** 2                              # squared distance ray - point
    r2 = _CAP_R[None, :] ** 2
    entry = t - np.sqrt(np.maximum(r2 - miss2, 0.0))
    hit = (miss2 < r2) & (entry > 0)
    z = np.where(hit, entry * d[:, 2:3], np.inf)
    return z.min(axis=1)


@dataclass(frozen=True)
class DepthSim:
    """The simulator's parameters (metres)."""

    sigma_k: float = SIGMA_K              # RMS = sigma_k * z^2
    hole_rate: float = 0.03
    background_rate: float = 0.02
    background_behind_m: tuple[float, float] = (1.0, 3.0)
    min_range_m: float = 0.2
    max_range_m: float = 10.0
    self_occlusion: bool = True

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
    if sim.self_occlusion:
        z = np.minimum(z, first_body_hit(p))   # another part of the body in front: the camera sees it
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
