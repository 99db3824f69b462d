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


def depth_fit(z_rel: np.ndarray, depth: np.ndarray) -> DepthFit | None:
    """The depth term for landmark depths ``z_rel`` (12, metres relative to the mid-hip, camera z) against
    the measured ``depth`` (12, metres, NaN unknown). None with fewer than MIN_DEPTHS measurements."""
    ok = np.isfinite(depth) & (depth > 0)
    if ok.sum() < MIN_DEPTHS:
        return None
    votes = depth[ok] + SURFACE_M[ok] - z_rel[ok]
    root = float(np.median(votes))
    sigma = math.hypot(DEPTH_RMS_K * root * root, SURFACE_SIGMA_M)
    near = np.abs(votes - root) < 3.0 * sigma
    if near.sum() >= MIN_DEPTHS:
        root = float(votes[near].mean())
    u2 = ((votes - root) / sigma) ** 2
    targets = np.full(12, np.nan)
    targets[ok] = depth[ok] + SURFACE_M[ok] - root
    weights = np.zeros(12)
    weights[ok] = 1.0 / (1.0 + u2) ** 2
    return DepthFit(float(np.sum(u2 / (1.0 + u2))), root, int(near.sum()), sigma, targets, weights)


def usable(fit: DepthFit | None, depth: np.ndarray) -> bool:
    """Whether the measured ``depth`` (12) agrees with a hypothesis whose term is ``fit``: at least half of
    the measured landmarks (and MIN_DEPTHS) within 3 sigma of one root depth. Uniformly scattered garbage
    over metres puts one or two of 12 votes in a 3 sigma window (about 25 cm at 3 m)."""
    if fit is None:
        return False
    measured = int((np.isfinite(depth) & (depth > 0)).sum())
    return fit.inliers >= max(MIN_DEPTHS, math.ceil(measured / 2))
