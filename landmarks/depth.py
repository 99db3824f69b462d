"""Depth at the landmarks: what an aligned depth image measures at each landmark's pixel (pure NumPy).

Frames and units. The depth image is aligned to the colour image the landmarks were found in: the same
``H x W`` pixel grid, pixel centres at integer coordinates (the image frame of :mod:`camera_model.intrinsics`:
x right, y down, origin at the centre of the top-left pixel). Its values are uint16 depth units, 0 where the
camera measured nothing; ``depth_scale`` metres per unit. A result is metres along the camera's z axis (the
optical axis, not the distance along the ray), float64, NaN where unknown.

The statistic. Each landmark reads a square patch of ``(2r + 1)²`` pixels centred on its nearest pixel,
clipped to the image; of its valid (non-zero) pixels it takes the lower median: the middle value, the nearer
of the two middle ones when their count is even. A median ignores a minority of outliers (speckle, a few
background pixels when the landmark sits near a silhouette edge), and the lower median is always a depth the
camera measured: a mean, or the midpoint of two middle values, can land between the body and the wall behind
it, where nothing is. When the patch straddles an edge the nearer surface (the body, usually) wins ties.

The patch. ``r`` defaults to :func:`depth_patch_radius`: 2 px at 480 lines, growing with the image's
shorter side (1 px per 240). BlazePose's landmark jitter is a few pixels at that size, so the patch covers
it, while 5 x 5 px stays inside a forearm or a shin at the distances a home robot sees a person from.

:func:`with_depth` puts the result on a :class:`~landmarks.LandmarkFrame` (its ``depth_m``), as the daemon's
landmark stage and ``posed landmarks`` do for every frame that comes with depth.

Unknown (NaN): a landmark whose x or y is NaN, whose nearest pixel is outside the image, or whose patch
holds fewer than a quarter of ``(2r + 1)²`` valid pixels (a hole in the depth image: glare, black cloth,
too near or too far for the camera).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from posed.landmarks.recording import LandmarkFrame


def depth_patch_radius(width: int, height: int) -> int:
    """The default patch radius in pixels for a ``width`` x ``height`` image: ``round(min(W, H) / 240)``,
    at least 1 (2 px at 640 x 480, 3 px at 1280 x 720)."""
    if width <= 0 or height <= 0:
        raise ValueError(f"the image size must be positive, got {width}x{height}")
    return max(1, math.floor(min(width, height) / 240.0 + 0.5))


def min_valid_pixels(radius: int) -> int:
    """How many valid pixels a patch of ``radius`` needs for a depth: a quarter of ``(2r + 1)²``, rounded up."""
    return -(-((2 * radius + 1) ** 2) // 4)


def sample_depth(depth: np.ndarray, depth_scale: float, landmarks: np.ndarray,
                 radius: int | None = None) -> np.ndarray:
    """The depth in metres at each landmark's pixel (see the module docstring for the statistic).

    depth        H x W uint16 depth image aligned to the landmarks' image, 0 = no depth
    depth_scale  metres per depth unit (> 0; a RealSense D4xx: 0.001)
    landmarks    N x K array (K >= 2), columns 0 and 1 = x, y in pixels of that image; NaN = unknown
                 (a :class:`~landmarks.LandmarkFrame`'s 33 x 5 ``[x_px, y_px, z, visibility, presence]``)
    radius       patch radius in pixels (default: :func:`depth_patch_radius` of the image)

    Returns N float64 depths in metres along the camera's z axis, NaN where unknown.
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or depth.dtype != np.uint16:
        raise ValueError(f"depth must be an H x W uint16 image aligned to the colour image, got shape "
                         f"{depth.shape} {depth.dtype}")
    if not (isinstance(depth_scale, (int, float, np.floating)) and math.isfinite(depth_scale)
            and depth_scale > 0):
        raise ValueError(f"depth_scale must be a positive number of metres per depth unit (0.001 for a "
                         f"RealSense D4xx), got {depth_scale!r}")
    points = np.asarray(landmarks, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] < 2:
        raise ValueError(f"landmarks must be N x K with x, y pixels in columns 0 and 1, got shape {points.shape}")
    h, w = depth.shape
    r = depth_patch_radius(w, h) if radius is None else int(radius)
    if r < 0:
        raise ValueError(f"radius must be >= 0 pixels, got {radius!r}")

    n = points.shape[0]
    out = np.full(n, np.nan)
    xy = points[:, :2]
    known = np.isfinite(xy).all(axis=1)
    centre = np.zeros((n, 2), np.int64)
    centre[known] = np.floor(xy[known] + 0.5).astype(np.int64)      # nearest pixel (centres at integers)
    inside = known & (centre[:, 0] >= 0) & (centre[:, 0] < w) & (centre[:, 1] >= 0) & (centre[:, 1] < h)
    if not inside.any():
        return out

    offsets = np.arange(-r, r + 1)
    cols = centre[inside, 0][:, None, None] + offsets[None, None, :]     # (m, 1, 2r+1)
    rows = centre[inside, 1][:, None, None] + offsets[None, :, None]     # (m, 2r+1, 1)
    in_image = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)      # (m, 2r+1, 2r+1)
    values = depth[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)].astype(np.float64)
    values = np.where(in_image & (values > 0), values, np.nan).reshape(values.shape[0], -1)
    count = np.count_nonzero(~np.isnan(values), axis=1)
    ordered = np.sort(values, axis=1)                                    # NaN sort last
    lower_median = np.take_along_axis(ordered, np.maximum(count - 1, 0)[:, None] // 2, axis=1)[:, 0]
    enough = count >= min_valid_pixels(r)
    out[np.flatnonzero(inside)] = np.where(enough, lower_median * float(depth_scale), np.nan)
    return out


def with_depth(frame: LandmarkFrame, depth: np.ndarray | None, depth_scale: float,
               radius: int | None = None) -> LandmarkFrame:
    """``frame`` with ``depth_m`` sampled (:func:`sample_depth`) from ``depth`` (H x W uint16 aligned to the
    frame's image, ``depth_scale`` metres per unit); the frame unchanged when there is no depth image, no
    depth scale (0: unknown) or no person. Every person of ``frame.people`` gets their own ``depth_m`` too."""
    if depth is None or frame.landmarks is None or not depth_scale > 0:
        return frame
    out = replace(frame, depth_m=sample_depth(depth, depth_scale, frame.landmarks, radius))
    if frame.people:
        out = replace(out, people=tuple(replace(p, depth_m=sample_depth(depth, depth_scale, p.landmarks, radius))
                                        for p in frame.people))
    return out
