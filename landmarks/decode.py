"""Landmark-model tensors → landmarks in the crop → landmarks in the image (tech-notes d.8).

Model outputs (pose_landmark_full): ``landmarks`` 39 × (x, y, z, visibility logit, presence logit) with x, y, z
in pixels of the 256×256 crop; ``pose_flag`` a probability; ``heatmap`` 64×64×39 logits; ``world`` 39 × 3
metres, origin between the hips, axes of the crop (x right, y down, z away from the camera).

Crop-normalized landmarks: x/256, y/256, z/256 (z on the x scale), sigmoid visibility and presence, then
``RefineLandmarksFromHeatmap`` (kernel 7, min confidence 0.5) — MediaPipe truncates x·64 and y·64 towards zero
for the window centre and skips a landmark only when the column is outside [0, 64) or the row is negative
(a row ≥ 64 just clips the window, possibly to nothing); both quirks are kept.

Image landmarks, pixels: ``x = cx + ((x−0.5)cosθ − (y−0.5)sinθ)·S``, ``y = cy + ((x−0.5)sinθ + (y−0.5)cosθ)·S``,
``z = z_norm·S`` (MediaPipe's ``z_norm·S/W`` times the image width W, i.e. pixels on the x scale).
"""

from __future__ import annotations

import math

import numpy as np

from posed.landmarks.detector import stable_sigmoid
from posed.landmarks.roi import Roi

NUM_ALL_LANDMARKS = 39
NUM_BODY_LANDMARKS = 33
AUX_START, AUX_END = 33, 34
CROP_SIZE = 256
HEATMAP_KERNEL = 7
MIN_CONFIDENCE_TO_REFINE = 0.5


def decode_crop_landmarks(raw: np.ndarray, crop_size: int = CROP_SIZE) -> np.ndarray:
    """(39, 5) float64 crop-normalized ``[x, y, z, visibility, presence]`` from the 195 raw values."""
    lm = np.asarray(raw, dtype=np.float64).reshape(NUM_ALL_LANDMARKS, 5).copy()
    lm[:, :3] /= crop_size
    lm[:, 3:] = stable_sigmoid(lm[:, 3:])
    return lm


def refine_from_heatmap(landmarks: np.ndarray, heatmap: np.ndarray, kernel: int = HEATMAP_KERNEL,
                        min_confidence: float = MIN_CONFIDENCE_TO_REFINE) -> np.ndarray:
    """Replace x, y by the confidence-weighted mean position of the heatmap window around each landmark.

    landmarks: (N, >=2) crop-normalized; heatmap: (H, W, N) logits (HWC). Returns a refined copy. The window
    is clipped at the heatmap border (cells outside count as zero weight).
    """
    hm = np.asarray(heatmap)
    hm_h, hm_w, channels = hm.shape
    n = landmarks.shape[0]
    if channels != n:
        raise ValueError(f"heatmap has {channels} channels for {n} landmarks")
    out = landmarks.copy()
    with np.errstate(invalid="ignore"):
        cols_f = np.trunc(landmarks[:, 0] * hm_w)
        rows_f = np.trunc(landmarks[:, 1] * hm_h)
    ok = np.isfinite(cols_f) & np.isfinite(rows_f)
    ok[ok] &= (cols_f[ok] >= 0) & (cols_f[ok] < hm_w) & (rows_f[ok] >= 0)
    if not ok.any():
        return out
    idx = np.flatnonzero(ok)
    offsets = np.arange(kernel) - (kernel - 1) // 2
    cols = cols_f[idx].astype(np.int64)[:, None] + offsets          # (M, k)
    rows = np.minimum(rows_f[idx], hm_h + kernel).astype(np.int64)[:, None] + offsets
    col_ok = (cols >= 0) & (cols < hm_w)
    row_ok = (rows >= 0) & (rows < hm_h)
    mask = row_ok[:, :, None] & col_ok[:, None, :]                   # (M, k, k)
    logits = hm[np.clip(rows, 0, hm_h - 1)[:, :, None], np.clip(cols, 0, hm_w - 1)[:, None, :],
                idx[:, None, None]]
    conf = np.where(mask, stable_sigmoid(logits), 0.0)
    total = conf.sum(axis=(1, 2))
    refine = (total > 0) & (conf.max(axis=(1, 2)) >= min_confidence)
    if refine.any():
        safe = np.where(total > 0, total, 1.0)
        mean_col = (conf * cols[:, None, :]).sum(axis=(1, 2)) / safe
        mean_row = (conf * rows[:, :, None]).sum(axis=(1, 2)) / safe
        sel = idx[refine]
        out[sel, 0] = mean_col[refine] / hm_w
        out[sel, 1] = mean_row[refine] / hm_h
    return out


def project_to_image(landmarks: np.ndarray, roi: Roi) -> np.ndarray:
    """Crop-normalized (N, 5) → image pixels (N, 5) ``[x, y, z, visibility, presence]``."""
    c, s = math.cos(roi.rotation), math.sin(roi.rotation)
    x = landmarks[:, 0] - 0.5
    y = landmarks[:, 1] - 0.5
    out = landmarks.copy()
    out[:, 0] = roi.cx + (c * x - s * y) * roi.size
    out[:, 1] = roi.cy + (s * x + c * y) * roi.size
    out[:, 2] = landmarks[:, 2] * roi.size
    return out


def rotate_world(world: np.ndarray, rotation: float) -> np.ndarray:
    """World landmarks (N, 3) metres with x, y rotated by the ROI rotation (``WorldLandmarkProjection``)."""
    c, s = math.cos(rotation), math.sin(rotation)
    out = np.asarray(world, dtype=np.float64).reshape(-1, 3).copy()
    x, y = out[:, 0].copy(), out[:, 1].copy()
    out[:, 0] = c * x - s * y
    out[:, 1] = s * x + c * y
    return out


def decode_pose(raw_landmarks: np.ndarray, heatmap: np.ndarray, raw_world: np.ndarray,
                roi: Roi) -> tuple[np.ndarray, np.ndarray]:
    """All 39 image landmarks (39, 5) pixels and world landmarks (39, 3) metres for one ROI."""
    crop = refine_from_heatmap(decode_crop_landmarks(raw_landmarks), np.asarray(heatmap).reshape(
        heatmap.shape[-3], heatmap.shape[-2], heatmap.shape[-1]))
    return project_to_image(crop, roi), rotate_world(raw_world, roi.rotation)
