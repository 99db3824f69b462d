import math

import numpy as np
import pytest

from posed.landmarks.crop import detector_input, landmark_input, letterbox_roi, roi_to_image_affine
from posed.landmarks.decode import project_to_image
from posed.landmarks.roi import Roi, normalize_radians, roi_from_alignment


@pytest.mark.parametrize("angle, want", [(0.0, 0.0), (math.pi, -math.pi), (-math.pi, -math.pi),
                                         (3 * math.pi / 2, -math.pi / 2), (-3 * math.pi / 2, math.pi / 2),
                                         (7.0, 7.0 - 2 * math.pi)])
def test_normalize_radians(angle, want):
    assert normalize_radians(angle) == pytest.approx(want)


def test_roi_of_an_upright_person():
    roi = roi_from_alignment(np.array([100.0, 300.0]), np.array([100.0, 200.0]))  # end point above the hips
    assert (roi.cx, roi.cy) == (100.0, 300.0)
    assert roi.size == pytest.approx(2.5 * 100) and roi.rotation == pytest.approx(0.0)


def test_roi_of_a_person_lying_head_right_is_rotated_clockwise():
    roi = roi_from_alignment(np.array([100.0, 300.0]), np.array([180.0, 300.0]))
    assert roi.rotation == pytest.approx(math.pi / 2) and roi.size == pytest.approx(200.0)
    # the crop's "up" (0, -1) must point from start to end (image +x)
    c, s = math.cos(roi.rotation), math.sin(roi.rotation)
    assert np.allclose([c * 0 - s * -1, s * 0 + c * -1], [1, 0])


def test_affine_maps_output_corners_to_roi_corners():
    roi = Roi(320.0, 200.0, 150.0, 0.7)
    m = roi_to_image_affine(roi, 256)
    out_corners = np.array([[0, 0, 1], [256, 0, 1], [256, 256, 1], [0, 256, 1]], float)
    assert np.allclose(out_corners @ m.T, roi.corners())


def test_landmark_projection_agrees_with_the_crop_warp():
    roi = Roi(410.0, 260.0, 333.0, -2.1)
    m = roi_to_image_affine(roi, 256)
    uv = np.array([[0.0, 0.0], [128.0, 64.0], [255.0, 10.0], [30.0, 200.0]])
    lms = np.zeros((4, 5))
    lms[:, :2] = uv / 256
    proj = project_to_image(lms, roi)
    assert np.allclose(proj[:, :2], np.c_[uv, np.ones(4)] @ m.T)


def _gradient_image(h, w):
    """BGR uint8 image whose red channel is 0.2*x + 0.3*y + 10 and blue channel 0.1*y + 50 (green 7)."""
    y, x = np.mgrid[0:h, 0:w].astype(float)
    img = np.empty((h, w, 3), np.uint8)
    img[..., 2] = np.round(0.2 * x + 0.3 * y + 10)
    img[..., 1] = 7
    img[..., 0] = np.round(0.1 * y + 50)
    return img


def test_landmark_crop_samples_the_rotated_roi_in_rgb_0_1():
    img = _gradient_image(480, 640)
    roi = Roi(330.0, 250.0, 200.0, 0.6)
    t = landmark_input(img, roi)
    assert t.shape == (1, 256, 256, 3) and t.dtype == np.float32
    m = roi_to_image_affine(roi, 256)
    v, u = np.mgrid[0:256:17, 0:256:17].astype(float)
    xy = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], 1) @ m.T
    red = 0.2 * xy[:, 0] + 0.3 * xy[:, 1] + 10
    got = t[0, v.astype(int).ravel(), u.astype(int).ravel()]
    assert np.abs(got[:, 0] * 255 - red).max() <= 1.0          # channel 0 is red (RGB)
    assert np.allclose(got[:, 1] * 255, 7)
    assert np.abs(got[:, 2] * 255 - (0.1 * xy[:, 1] + 50)).max() <= 1.0


def test_landmark_crop_replicates_the_border():
    img = _gradient_image(100, 100)
    t = landmark_input(img, Roi(0.0, 0.0, 400.0, 0.0))  # mostly outside the image
    assert t[0, 0, 0, 0] == pytest.approx(img[0, 0, 2] / 255)  # replicated, not black
    assert np.allclose(t[0, :100, :100, 1], 7 / 255)


def test_detector_input_letterboxes_with_minus_one():
    img = np.full((667, 1000, 3), 255, np.uint8)
    t, padding = detector_input(img)
    assert t.shape == (1, 224, 224, 3)
    pad = (1 - 667 / 1000) / 2
    assert padding == pytest.approx((0.0, pad, 0.0, pad))
    rows = int(pad * 224)
    assert (t[0, : rows - 1] == -1).all() and (t[0, -(rows - 1):] == -1).all()
    assert (t[0, 112] == 1).all()


def test_letterbox_roi_of_a_portrait_frame():
    roi, padding = letterbox_roi(720, 1280)
    assert roi == Roi(360.0, 640.0, 1280.0, 0.0)
    assert padding == pytest.approx(((1 - 720 / 1280) / 2, 0.0, (1 - 720 / 1280) / 2, 0.0))
