"""A frame's 12 body landmarks as the fit reads them: their weights, the reference scale and their normalized
coordinates in the kernels' data array. numba, ``cache=True``; one call each per frame
(fitting.problem.landmark_weights, reference_scale and pack are their Python interface; the plain-Python
functions they replaced are the references in ``tests/fitting/test_packing.py``, equal to the last bit).

Pixels in; pixels per metre for the scale; normalized units (fitting.problem) in the data array; segment
lengths in metres.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# body-12 index pairs of the segments that set the reference scale (their lengths: fitting.problem._SCALE_LENGTHS):
# shoulders, hips, upper arms, thighs, shanks; then the trunk, mid-hip to mid-shoulder
SCALE_PAIRS = ((0, 1), (6, 7), (0, 2), (1, 3), (6, 8), (7, 9), (8, 10), (9, 11))


@njit(cache=True)
def weights_into(landmarks, body_idx, drop, span, xy, w):
    """``xy`` (12 x 2, pixels) and ``w`` (12) of the body landmarks ``body_idx`` of ``landmarks`` (33 x 5:
    x, y, z, visibility, presence); returns how many are unusable. A landmark is unusable when x, y or
    visibility is not finite or visibility < ``drop`` (position 0, weight 0); weights rise linearly from
    0.05 at ``drop`` to 1 at ``drop + span``."""
    missing = 0
    for i in range(body_idx.size):
        row = body_idx[i]
        x, y, vis = landmarks[row, 0], landmarks[row, 1], landmarks[row, 3]
        if math.isfinite(x) and math.isfinite(y) and math.isfinite(vis) and not vis < drop:
            xy[i, 0] = x
            xy[i, 1] = y
            w[i] = min(max((vis - drop) / span, 0.05), 1.0)
        else:
            xy[i, 0] = 0.0
            xy[i, 1] = 0.0
            w[i] = 0.0
            missing += 1
    return missing


@njit(cache=True)
def reference_scale_of(xy, w, lengths, trunk):
    """Pixels per metre: the largest ratio of a projected segment to its model length (projection only
    shortens) over the SCALE_PAIRS segments (``lengths``, metres, that order) and the trunk (``trunk``) whose
    landmarks all have weight > 0; 0 when none has."""
    best = 0.0
    for s in range(len(SCALE_PAIRS)):
        a, b = SCALE_PAIRS[s]
        if w[a] > 0 and w[b] > 0:
            best = max(best, math.hypot(xy[a, 0] - xy[b, 0], xy[a, 1] - xy[b, 1]) / lengths[s])
    if w[0] > 0 and w[1] > 0 and w[6] > 0 and w[7] > 0:
        dx = 0.5 * (xy[0, 0] + xy[1, 0]) - 0.5 * (xy[6, 0] + xy[7, 0])
        dy = 0.5 * (xy[0, 1] + xy[1, 1]) - 0.5 * (xy[6, 1] + xy[7, 1])
        best = max(best, math.hypot(dx, dy) / trunk)
    return best


@njit(cache=True)
def weight_sum(w):
    """``w.sum()`` of 12 weights as NumPy 2 sums them (eight running sums combined pairwise, then the rest in
    turn): the same float as before this kernel."""
    acc = ((w[0] + w[1]) + (w[2] + w[3])) + ((w[4] + w[5]) + (w[6] + w[7]))
    for i in range(8, w.size):
        acc += w[i]
    return acc


@njit(cache=True)
def normalized_into(xy, w, scale_px, data, d_obs, d_w):
    """The landmarks in normalized units into ``data``: relative to their weighted centroid and divided by
    ``scale_px`` (pixels per normalized unit), x and y in turn from ``data[d_obs]``, and the weights from
    ``data[d_w]``; returns the centroid (pixels; NaN when every weight is 0, as NumPy's 0 / 0). ``w``: the 12
    body landmarks' weights (:func:`weight_sum`)."""
    sw = weight_sum(w)
    sx = 0.0
    sy = 0.0
    for i in range(w.size):
        sx += w[i] * xy[i, 0]
        sy += w[i] * xy[i, 1]
    cx = sx / sw if sw != 0.0 else np.nan
    cy = sy / sw if sw != 0.0 else np.nan
    for i in range(w.size):
        data[d_obs + 2 * i] = (xy[i, 0] - cx) / scale_px
        data[d_obs + 2 * i + 1] = (xy[i, 1] - cy) / scale_px
        data[d_w + i] = w[i]
    return cx, cy
