"""The floor plane from a depth camera's point cloud (issue 33 item 1a): camera height, tilt and roll with no
person in view. Pure NumPy; the caller deprojects the depth image (:func:`points_from_depth`).

Camera axes: x image right, y image down, z forward (metres). The floor is the plane ``n . p = h`` with ``n``
the down direction (gravity, unit) and ``h`` > 0 the camera's height above it.

Method: RANSAC over planes through three points whose normal is within ``max_angle_deg`` of the prior down
direction (the IMU's gravity when there is one, 10 deg; else a camera pitched anywhere from level to 60 deg
down: 45 deg around 30 deg down) — walls and most furniture sides are then never candidates. The floor is the
best-supported such plane holding at least ``min_fraction`` of the points, unless a plane parallel to it
lies lower and is supported too: a table top or a bed can hold more points than the visible floor, but lies
above it. The winner is refined by least squares (the smallest singular vector of its inliers). A winner cut
across two raised surfaces (a table top and a bed together outnumbering a small visible floor: its normal a few
degrees off, so the floor under it is no sharp level along it) is stepped down too: a plane within
``CUT_ACROSS_DEG`` of it among the points under it.

Cost: the candidates are drawn and scored together (NumPy, no Python loop over them), scored on at most
``SCORE_POINTS`` points in float32: 2.1 ms median, 7 ms at most (a step down past a cut-across plane) for
4000 points and 400 candidates (the daemon's decimated depth image) on the 2-core development machine; the loop
over candidates before took 15 ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics

PARALLEL_DEG = 5.0      # a table top, a bed and the floor are parallel to within this
LEVEL_GAP_M = 0.15     # ... and a surface this far below the best-supported one is another level (the floor)
CUT_ACROSS_DEG = 10.0  # a plane cut across a table top and a bed is this close to the floor's (1.6 m apart: 9 deg)
LOWER_ITERATIONS = 200  # candidates for a lower level under a plane cut across two
SCORE_BLOCK = 64       # candidate planes scored together (points x 64 distances at a time)
SCORE_POINTS = 2000    # candidates are scored on this many of the points (the winner is refined on all)


@dataclass(frozen=True)
class FloorPlane:
    """The fitted floor: ``down`` (unit, camera axes), ``height_m`` (camera above it), ``tilt_deg``/``roll_deg``
    (as ``falls.features.gravity_from_tilt``), how many points support it and their rms distance to it."""

    down: np.ndarray
    height_m: float
    tilt_deg: float
    roll_deg: float
    inliers: int
    points: int
    rms_m: float

    @property
    def fraction(self) -> float:
        """The share of the points on the floor."""
        return self.inliers / self.points if self.points else 0.0


def points_from_depth(depth_m: np.ndarray, camera: Intrinsics, stride: int = 4, max_depth_m: float = 8.0,
                      depth_scale: float = 1.0) -> np.ndarray:
    """(N, 3) camera-axes points of every ``stride``-th pixel of a depth image (metres, or raw units of
    ``depth_scale`` metres: a RealSense's uint16; 0 or non-finite = none); ``camera``: the image's intrinsics."""
    d = np.asarray(depth_m)[::stride, ::stride].astype(np.float64) * depth_scale
    v, u = np.mgrid[0:d.shape[0], 0:d.shape[1]] * stride
    ok = np.isfinite(d) & (d > 0.1) & (d < max_depth_m)
    z = d[ok]
    return np.stack([(u[ok] - camera.cx) * z / camera.fx, (v[ok] - camera.cy) * z / camera.fy, z], axis=1)


def fit_floor(points: np.ndarray, prior_down: np.ndarray | None = None, max_angle_deg: float | None = None,
              inlier_m: float = 0.03, min_fraction: float = 0.03, iterations: int = 400,
              seed: int = 0) -> FloorPlane | None:
    """The floor plane of ``points`` (N x 3, camera axes), or None when no horizontal plane below the camera
    holds ``min_fraction`` of them. ``prior_down``: gravity (an IMU's, any length) — candidates within
    ``max_angle_deg`` (default 10) of it; None: within 60 deg of image-down (a camera from level to 60 deg down,
    rolled a little)."""
    from posed.falls.geometry import tilt_roll_deg

    p = np.asarray(points, float)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) < 50:
        return None
    if prior_down is None:
        # a camera from level to 60 deg down sees the floor's normal between image-down and 60 deg towards
        # forward: a cone of 45 deg around the middle (30 deg down) holds them all, with some roll
        prior = np.array([0.0, math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
        limit = 45.0 if max_angle_deg is None else max_angle_deg
    else:
        prior = np.asarray(prior_down, float) / np.linalg.norm(prior_down)
        limit = 10.0 if max_angle_deg is None else max_angle_deg
    cos_limit = math.cos(math.radians(limit))
    rng = np.random.default_rng(seed)
    need = max(int(min_fraction * len(p)), 30)
    best = _best_candidate(p, prior, cos_limit, iterations, rng, inlier_m)
    if best is None or best[2] < need:
        return None
    n_c, h_c, _ = best
    # the best-supported plane, unless a parallel surface lower down (the floor under a table top or a bed that
    # holds more points) is supported too: the densest level among the points below it, along its normal
    n_best, h_best, mask_best = _refine(p, np.abs(p @ n_c - h_c) < inlier_m, prior, inlier_m)
    for _ in range(3):                # a table top above a bed above the floor: step down level by level
        lower = _lower_level(p, n_best, h_best, need, inlier_m, rng)
        if lower is None:
            break
        n_best, h_best, mask_best = lower
    n, h, mask = n_best, h_best, mask_best
    tilt, roll = tilt_roll_deg(n)
    resid = p[mask] @ n - h
    return FloorPlane(down=n, height_m=h, tilt_deg=tilt, roll_deg=roll, inliers=int(mask.sum()), points=len(p),
                      rms_m=float(np.sqrt(np.mean(resid ** 2))))


def _best_candidate(p: np.ndarray, prior: np.ndarray, cos_limit: float, iterations: int, rng, inlier_m: float):
    """RANSAC: planes through three random points, all drawn and scored at once, kept when their normal is
    within ``cos_limit`` of ``prior`` and they lie below the camera. (n, h, support over all points) of the
    best-supported, or None."""
    a, b, c = (p[i] for i in rng.integers(0, len(p), size=(3, iterations)))
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-9                                  # three distinct points not on one line
    n, a = n[ok] / norm[ok, None], a[ok]
    n *= np.where(n @ prior < 0, -1.0, 1.0)[:, None]
    h = np.einsum("ij,ij->i", n, a)
    ok = (n @ prior >= cos_limit) & (h > 0.1)         # not a wall, nor a plane no floor can be; below the camera
    n, h = n[ok], h[ok]
    if len(n) == 0:
        return None
    # scored on at most SCORE_POINTS of the points (float32: the inlier band is 3 cm, far above its rounding)
    q = (p if len(p) <= SCORE_POINTS else p[rng.choice(len(p), SCORE_POINTS, replace=False)]).astype(np.float32)
    n32, h32 = n.astype(np.float32), h.astype(np.float32)
    support = np.concatenate([(np.abs(q @ n32[i:i + SCORE_BLOCK].T - h32[i:i + SCORE_BLOCK]) < inlier_m).sum(axis=0)
                              for i in range(0, len(n), SCORE_BLOCK)])
    k = int(np.argmax(support))
    return n[k], float(h[k]), int(support[k]) * len(p) / len(q)


def _lower_level(p: np.ndarray, n: np.ndarray, h: float, need: int, inlier_m: float, rng):
    """The densest level parallel to the plane (n, h) among the points more than LEVEL_GAP_M below it, refined;
    None when none holds ``need`` points."""
    heights = p @ n
    below = heights > h + LEVEL_GAP_M
    low = heights[below]
    if len(low) < need:
        return None
    edges = np.arange(low.min(), low.max() + 2 * inlier_m, inlier_m)
    counts = np.histogram(low, bins=edges)[0]
    if len(counts) >= 2:
        pair = counts[:-1] + counts[1:]
        k = int(np.argmax(pair))
        if int(pair[k]) >= need:
            n_low, h_low, m_low = _refine(p, np.abs(heights - float(edges[k + 1])) < inlier_m, n, inlier_m)
            if float(n_low @ n) >= math.cos(math.radians(PARALLEL_DEG)) and int(m_low.sum()) >= need:
                return n_low, h_low, m_low
    # the plane above can be one cut across two levels (a table top and a bed: their points together outnumber
    # the floor's); its normal is then a few degrees off, and the floor under it is smeared over many of those
    # bins: look for a plane near its normal among the points below it instead
    best = _best_candidate(p[below], n, math.cos(math.radians(CUT_ACROSS_DEG)), LOWER_ITERATIONS, rng, inlier_m)
    if best is None:
        return None
    n_c, h_c, _ = best
    n_low, h_low, m_low = _refine(p, np.abs(p @ n_c - h_c) < inlier_m, n, inlier_m)
    if float(n_low @ n) < math.cos(math.radians(CUT_ACROSS_DEG)) or int(m_low.sum()) < need \
            or h_low < h + LEVEL_GAP_M / 2:
        return None
    return n_low, h_low, m_low


def _refine(p: np.ndarray, mask: np.ndarray, prior: np.ndarray, inlier_m: float, rounds: int = 3):
    """Least-squares plane of the inliers, re-selecting them a few times."""
    n, h = prior, 0.0
    for _ in range(rounds):
        q = p[mask]
        centre = q.mean(axis=0)
        _u, _s, vt = np.linalg.svd(q - centre, full_matrices=False)
        n = vt[-1]
        if float(n @ prior) < 0:
            n = -n
        h = float(n @ centre)
        mask = np.abs(p @ n - h) < inlier_m
    return n, h, mask
