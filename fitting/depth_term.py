"""The depth term: what an aligned depth camera measured at the 12 body landmarks, against a 3D hypothesis.

Depth is metres along the camera's z axis (interfaces.md section 1, ``depth_m``). It is not the joint's
depth: a depth camera sees the body's **surface**, a few centimetres in front of the joint centre
(:data:`SURFACE_M`), or whatever is **in front of** a hidden joint (an arm across the body, a table), or, at
a silhouette edge, the **background** metres behind; and it has **holes** (NaN). So the term is robust:

* each landmark with a depth votes for the mid-hip's depth: ``d_i + s_i - Z_i`` (``Z_i``: the hypothesis'
  landmark depth relative to the mid-hip, camera axes); the root depth is the median of the votes, refined
  by the mean of those within 3 sigma of it;
* each vote's deviation ``u_i`` from it, in units of the expected spread sigma(z) — the camera's RMS error
  :data:`DEPTH_RMS_K` z^2 (a RealSense D435-like stereo camera: about 3 cm at 3 m) combined with the
  surface offset's own spread :data:`SURFACE_SIGMA_M` — costs ``u^2 / (1 + u^2)`` (Geman-McClure): at most 1
  per landmark, so an occluder or a background hit can never outweigh the landmarks.

A joint the hypothesis puts **behind another part of its own body** (the far shoulder and hip behind the
torso seen from the side, the far knee behind the near leg: :func:`occluder_front`) cannot be seen: the camera
measures that part's near surface there, so that landmark's vote uses the occluder's front instead of the
joint's own surface, and it gets no refinement row (its measured depth says where the occluder is, not where
the joint is). Without this a hypothesis that brings the hidden limb forward onto the occluder's surface
explains the measurement better than the true one. The body is a few capsules (:data:`CAPSULES`), each
landmark looked at along its own pixel's ray (with a pinhole camera; along the optical axis without one).

Fewer than :data:`MIN_DEPTHS` depths: no term (a recording without depth is fitted exactly as before).
And depth that no hypothesis of the frame agrees with on at least half of the measured landmarks
(:func:`usable`) is not depth of this person — a misaligned or wrongly scaled depth image, garbage — and the
frame is fitted without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# how far in front of the joint centre the body's surface is, metres, for the 12 body landmarks in
# fitting.kinematics.BODY_LANDMARKS order (shoulders, elbows, wrists, hips, knees, ankles): about half the
# limb's thickness (adult anthropometry: upper arm ~9 cm, forearm ~7 cm, wrist ~5 cm, thigh ~15 cm at the
# hip, knee ~10 cm, ankle ~7 cm across)
SURFACE_M = np.array([0.05, 0.05, 0.04, 0.04, 0.03, 0.03, 0.08, 0.08, 0.05, 0.05, 0.04, 0.04])
SURFACE_SIGMA_M = 0.03   # the surface offset varies with the view and clothing
DEPTH_RMS_K = 0.0033     # m / m^2: depth RMS error k z^2 (about 3 cm at 3 m), a D435-like camera
MIN_DEPTHS = 3           # at least this many landmarks with a depth for the term to apply
# the body as capsules (a, a', b, b'): from mean(a, a') to mean(b, b'), body-12 indices. The torso: three
# upright capsules, each shoulder to the same side's hip and the mid-shoulder to the mid-hip; the limbs: each
# segment (upper arm, forearm, thigh, shank, left then right)
CAPSULES = ((0, 0, 6, 6), (1, 1, 7, 7), (0, 1, 6, 7),
            (0, 0, 2, 2), (1, 1, 3, 3), (2, 2, 4, 4), (3, 3, 5, 5),
            (6, 6, 8, 8), (7, 7, 9, 9), (8, 8, 10, 10), (9, 9, 11, 11))
TORSO_HALF_DEPTH_M = 0.10   # the torso's radius: half an adult's chest and waist depth (20-25 cm)
# radii, metres: the torso; the limbs about their surface offsets (SURFACE_M at the segment's lower joint)
CAPSULE_RADII = (TORSO_HALF_DEPTH_M,) * 3 + (0.04, 0.04, 0.03, 0.03, 0.05, 0.05, 0.04, 0.04)
HIDDEN_MARGIN_M = 0.03   # hidden: the occluder's front at least this much nearer than the joint's own surface

# What the measured depths are (the term's "sensor", a kernel argument): (surface offsets: 1 on / 0 off,
# occlusions: 1 seen / 0 not, sigma: 0 = the depth camera's model above, else this fixed spread in metres).
# A depth camera sees the body's surface and what is in front of a hidden joint. BlazePose's world landmarks
# (fitting.world_term) are joint centres, hidden or not, with a spread of their own.
SENSOR_DEPTH_CAMERA = np.array([1.0, 1.0, 0.0])


def occluder_front(pts: np.ndarray, slopes: np.ndarray | None = None) -> np.ndarray:
    """For each of the 12 body landmarks at ``pts`` (12 x 3, metres, camera axes: z away from the camera), the
    depth of the nearest other body part's front surface on its line of sight (:data:`CAPSULES`) where that is
    at least HIDDEN_MARGIN_M nearer than the landmark's own surface (``z - SURFACE_M``): the landmark is hidden;
    +inf where it is not. A capsule never hides its own end points.

    The line of sight of landmark i has the slopes ``slopes[i]`` = (dx/dz, dy/dz) (12 x 2: a pinhole camera's
    ``(u - cx) / fx, (v - cy) / fy`` at its pixel; None: along the optical axis, orthographic); the test is
    made in coordinates sheared along it (``x - sx z, y - sy z``), where the ray is parallel to z."""
    front = np.full(12, np.inf)
    own = pts[:, 2] - SURFACE_M
    sl = np.zeros((12, 2)) if slopes is None else np.asarray(slopes, dtype=np.float64)
    for (a0, a1, b0, b1), r in zip(CAPSULES, CAPSULE_RADII, strict=True):
        a = 0.5 * (pts[a0] + pts[a1])
        b = 0.5 * (pts[b0] + pts[b1])
        for i in range(12):
            if i in (a0, a1, b0, b1):
                continue
            shear = np.array([[1.0, 0.0, -sl[i, 0]], [0.0, 1.0, -sl[i, 1]]])   # (x, y, z) -> sheared (x, y)
            a2, u2, p2 = shear @ a, shear @ (b - a), shear @ pts[i]
            uu = float(u2 @ u2)
            s = 0.0 if uu <= 1e-12 else min(max(float((p2 - a2) @ u2) / uu, 0.0), 1.0)
            miss2 = float(np.sum((p2 - a2 - s * u2) ** 2))
            if miss2 < r * r:
                z = a[2] + s * (b[2] - a[2]) - math.sqrt(r * r - miss2)
                if z < own[i] - HIDDEN_MARGIN_M and z < front[i]:
                    front[i] = z
    return front


@dataclass(frozen=True)
class DepthFit:
    """The depth term of one hypothesis: ``cost`` (sum of the robust per-landmark costs, each in [0, 1)),
    ``root_z`` (the mid-hip's depth the measurements give, metres), ``inliers`` (votes within 3 sigma),
    ``sigma`` (the expected spread at that depth, metres), and for the refinement's depth rows the targets
    (12: each landmark's depth relative to the mid-hip that its measurement implies, NaN unknown) and the
    robust weights (12: Geman-McClure's 1 / (1 + u^2)^2, 0 where unknown)."""

    cost: float
    root_z: float
    inliers: int
    sigma: float
    targets: np.ndarray
    weights: np.ndarray


def depth_fit(z_rel: np.ndarray, depth: np.ndarray, front: np.ndarray | None = None,
              sensor: np.ndarray = SENSOR_DEPTH_CAMERA) -> DepthFit | None:
    """The depth term for landmark depths ``z_rel`` (12, metres relative to the mid-hip, camera z) against
    the measured ``depth`` (12, metres, NaN unknown); ``front``: :func:`occluder_front` of the hypothesis (None:
    nothing hidden; ignored when the ``sensor`` sees no occlusions). None with fewer than MIN_DEPTHS
    measurements."""
    ok = np.isfinite(depth) & (depth > 0)
    if ok.sum() < MIN_DEPTHS:
        return None
    surface = SURFACE_M * sensor[0]
    hidden = np.isfinite(front) if front is not None and sensor[1] > 0 else np.zeros(12, dtype=bool)
    seen = np.where(hidden, front, z_rel - surface)   # the surface the camera should see, relative
    votes = depth[ok] - seen[ok]
    root = float(np.median(votes))
    sigma = math.hypot(DEPTH_RMS_K * root * root, SURFACE_SIGMA_M) if not sensor[2] > 0 else float(sensor[2])
    near = np.abs(votes - root) < 3.0 * sigma
    if near.sum() >= MIN_DEPTHS:
        root = float(votes[near].mean())
    u2 = ((votes - root) / sigma) ** 2
    targets = np.full(12, np.nan)
    targets[ok] = depth[ok] + surface[ok] - root
    weights = np.zeros(12)
    weights[ok] = 1.0 / (1.0 + u2) ** 2
    targets[hidden] = np.nan      # a hidden joint's depth is the occluder's: no row for the joint
    weights[hidden] = 0.0
    return DepthFit(float(np.sum(u2 / (1.0 + u2))), root, int(near.sum()), sigma, targets, weights)


def usable(fit: DepthFit | None, depth: np.ndarray) -> bool:
    """Whether the measured ``depth`` (12) agrees with a hypothesis whose term is ``fit``: at least half of
    the measured landmarks (and MIN_DEPTHS) within 3 sigma of one root depth. Uniformly scattered garbage
    over metres puts one or two of 12 votes in a 3 sigma window (about 25 cm at 3 m)."""
    if fit is None:
        return False
    measured = int((np.isfinite(depth) & (depth > 0)).sum())
    return fit.inliers >= max(MIN_DEPTHS, math.ceil(measured / 2))
