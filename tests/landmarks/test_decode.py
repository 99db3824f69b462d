import math

import numpy as np
import pytest

from posed.landmarks.decode import (
    decode_crop_landmarks,
    decode_pose,
    project_to_image,
    refine_from_heatmap,
    rotate_world,
)
from posed.landmarks.roi import Roi


def _reference_refine(lms, hm, kernel=7, min_conf=0.5):
    """MediaPipe's RefineLandmarksFromHeatMap written as its plain double loop (C++ int truncation, and its
    check of the column twice instead of the row)."""
    out = lms.copy()
    hm_h, hm_w, _ = hm.shape
    off = (kernel - 1) // 2
    for i in range(lms.shape[0]):
        if not (math.isfinite(lms[i, 0]) and math.isfinite(lms[i, 1])):
            continue
        col, row = int(lms[i, 0] * hm_w), int(lms[i, 1] * hm_h)
        if col < 0 or col >= hm_w or row < 0 or col >= hm_h:
            continue
        total = wc = wr = mx = 0.0
        for r in range(max(0, row - off), min(hm_h, row + off + 1)):
            for c in range(max(0, col - off), min(hm_w, col + off + 1)):
                conf = 1 / (1 + math.exp(-hm[r, c, i]))
                total += conf
                mx = max(mx, conf)
                wc += c * conf
                wr += r * conf
        if mx >= min_conf and total > 0:
            out[i, 0] = wc / hm_w / total
            out[i, 1] = wr / hm_h / total
    return out


def test_refinement_matches_the_plain_loop_including_edges():
    rng = np.random.default_rng(3)
    n = 39
    hm = rng.normal(-1.0, 2.0, size=(64, 64, n))
    lms = rng.uniform(-0.05, 1.05, size=(n, 5))
    lms[0, :2] = [-0.001, 0.5]    # truncates to column 0 (MediaPipe keeps it), floor would drop it
    lms[1, :2] = [0.5, 1.02]      # row 65: window clipped to rows 62-63
    lms[2, :2] = [0.5, 1.2]       # row 76: empty window, unchanged
    lms[3, :2] = [np.nan, 0.5]
    lms[4, :2] = [0.999, 0.0]
    hm[:, :, 5] = -10.0           # nowhere confident: unchanged
    got = refine_from_heatmap(lms, hm)
    want = _reference_refine(lms, hm)
    assert np.allclose(got, want, equal_nan=True)
    assert np.array_equal(got[5], lms[5]) and np.array_equal(got[2], lms[2])
    assert not np.array_equal(got[0], lms[0]) and not np.array_equal(got[1], lms[1])


def test_refinement_pulls_a_landmark_to_a_heatmap_peak():
    hm = np.full((64, 64, 1), -20.0)
    hm[30, 22, 0] = 20.0
    lms = np.array([[21.5 / 64, 31.2 / 64, 0, 1, 1]])
    got = refine_from_heatmap(lms, hm)
    assert got[0, :2] == pytest.approx([22 / 64, 30 / 64], abs=1e-6)


def test_crop_landmarks_are_normalized_and_activated():
    raw = np.zeros(195)
    raw[0:5] = [128.0, 64.0, -25.6, 0.0, 2.0]
    lm = decode_crop_landmarks(raw)
    assert lm.shape == (39, 5)
    assert lm[0].tolist() == pytest.approx([0.5, 0.25, -0.1, 0.5, 1 / (1 + math.exp(-2.0))])


def test_projection_to_image_pixels_with_rotation():
    lms = np.array([[0.5, 0.5, 0.1, 0.9, 0.8], [0.5, 0.0, 0.0, 1, 1]])
    roi = Roi(100.0, 200.0, 50.0, math.pi / 2)
    out = project_to_image(lms, roi)
    assert out[0].tolist() == pytest.approx([100.0, 200.0, 5.0, 0.9, 0.8])  # z scaled like x (pixels)
    assert out[1, :2].tolist() == pytest.approx([125.0, 200.0])  # crop top -> image right at +90 deg


def test_world_landmarks_rotate_with_the_roi():
    w = rotate_world(np.array([1.0, 0.0, 0.3, 0.0, -1.0, 0.0]), math.pi / 2)
    assert np.allclose(w, [[0, 1, 0.3], [1, 0, 0]])


def test_decode_pose_shapes():
    rng = np.random.default_rng(0)
    raw = rng.uniform(0, 256, (39, 5))
    raw[:, 3:] = rng.normal(0, 3, (39, 2))  # logits
    lms, world = decode_pose(raw.ravel(), rng.normal(size=(64, 64, 39)), rng.normal(size=117), Roi(50, 60, 100, 0.2))
    assert lms.shape == (39, 5) and world.shape == (39, 3)
    assert ((lms[:, 3:] > 0) & (lms[:, 3:] < 1)).all()
