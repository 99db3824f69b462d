"""Image → model input tensors, as MediaPipe's ``ImageToTensorCalculator`` (OpenCV path) builds them.

MediaPipe maps the four corners of the (rotated) region onto the corners of the output, 0 and N, with
``warpPerspective`` and bilinear interpolation on the 8-bit image, then converts to float. For a square region
and a square output that warp is the affine map

    image = centre + R(rotation) · ((u/N − 0.5)·S, (v/N − 0.5)·S)

from output pixel (u, v) to the image (S = region side in pixels), which is what is used here
(``cv2.warpAffine`` with ``WARP_INVERSE_MAP``). Tensors are NHWC float32, RGB.

* Detector (tech-notes d.2): the whole frame letterboxed into 224×224 (region = the frame's longer side,
  centred), ``BORDER_CONSTANT`` 0, values ``px/127.5 − 1`` in [−1, 1] (padding becomes −1).
* Landmark model (d.7): the rotated square ROI into 256×256, ``BORDER_REPLICATE``, values ``px/255``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from posed.landmarks.anchors import INPUT_SIZE as DETECTOR_INPUT
from posed.landmarks.decode import CROP_SIZE
from posed.landmarks.roi import Roi


def roi_to_image_affine(roi: Roi, out_size: int) -> np.ndarray:
    """2×3 matrix taking output pixel (u, v, 1) to image pixels (x, y)."""
    c, s = math.cos(roi.rotation), math.sin(roi.rotation)
    k = roi.size / out_size
    a = np.array([[c * k, -s * k], [s * k, c * k]])
    b = np.array([roi.cx, roi.cy]) - a @ np.array([out_size / 2, out_size / 2])
    return np.hstack([a, b[:, None]])


def warp_roi(image_bgr: np.ndarray, roi: Roi, out_size: int, border: int) -> np.ndarray:
    """The ROI resampled to ``out_size``×``out_size`` (uint8 BGR, bilinear, given OpenCV border mode)."""
    return cv2.warpAffine(image_bgr, roi_to_image_affine(roi, out_size), (out_size, out_size),
                          flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=border, borderValue=0)


def letterbox_roi(width: int, height: int) -> tuple[Roi, tuple[float, float, float, float]]:
    """The square region around the whole frame, and the padding it adds.

    Padding ``(left, top, right, bottom)`` is normalized to the letterboxed square (MediaPipe's ``PadRoi``).
    """
    side = float(max(width, height))
    pad_x = (1.0 - width / side) / 2
    pad_y = (1.0 - height / side) / 2
    return Roi(width / 2, height / 2, side, 0.0), (pad_x, pad_y, pad_x, pad_y)


def detector_input(image_bgr: np.ndarray, size: int = DETECTOR_INPUT) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Detector tensor (1, size, size, 3) float32 RGB in [−1, 1] and the letterbox padding."""
    h, w = image_bgr.shape[:2]
    roi, padding = letterbox_roi(w, h)
    patch = warp_roi(image_bgr, roi, size, cv2.BORDER_CONSTANT)
    tensor = cv2.cvtColor(patch, cv2.COLOR_BGR2RGB).astype(np.float32)
    tensor *= np.float32(2.0 / 255.0)
    tensor -= np.float32(1.0)
    return tensor[None], padding


def landmark_input(image_bgr: np.ndarray, roi: Roi, size: int = CROP_SIZE) -> np.ndarray:
    """Landmark-model tensor (1, size, size, 3) float32 RGB in [0, 1] from the rotated ROI."""
    patch = warp_roi(image_bgr, roi, size, cv2.BORDER_REPLICATE)
    tensor = cv2.cvtColor(patch, cv2.COLOR_BGR2RGB).astype(np.float32)
    tensor *= np.float32(1.0 / 255.0)
    return tensor[None]
