"""The rotated square region of interest that the landmark model looks at.

Image pixel frame throughout: OpenCV coordinates of the full frame, x right, y down, a pixel's centre at
integer coordinates (MediaPipe's normalized coordinates times the image size). A rotation is in radians,
positive turning the crop's "up" towards the image's right (clockwise on screen, because y points down).

Both ways of getting an ROI are MediaPipe's ``AlignmentPointsRectsCalculator`` followed by
``RectTransformationCalculator`` (tech-notes d.6, d.9): the centre is the start point, the side is twice the
distance start→end, the rotation brings the start→end vector to "up" (target angle 90°), then ``square_long``
(already square in pixels) and a scale of 1.25.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ROI_SCALE = 1.25
TARGET_ANGLE = math.pi / 2


@dataclass(frozen=True)
class Roi:
    """A square region of the image: centre (cx, cy) and side ``size`` in pixels, ``rotation`` in radians."""

    cx: float
    cy: float
    size: float
    rotation: float

    def corners(self) -> np.ndarray:
        """The four corners in image pixels, (4, 2): crop top-left, top-right, bottom-right, bottom-left."""
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        half = self.size / 2
        local = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
        rot = np.array([[c, -s], [s, c]])
        return local @ rot.T + np.array([self.cx, self.cy])


def normalize_radians(angle: float) -> float:
    """Wrap an angle to [-pi, pi) as MediaPipe's ``NormalizeRadians`` does."""
    return angle - 2 * math.pi * math.floor((angle + math.pi) / (2 * math.pi))


def alignment_rotation(start_xy: np.ndarray, end_xy: np.ndarray) -> float:
    """Rotation that turns the start→end vector (image pixels) to point up in the crop."""
    dx = float(end_xy[0] - start_xy[0])
    dy = float(end_xy[1] - start_xy[1])
    return normalize_radians(TARGET_ANGLE - math.atan2(-dy, dx))


def alignment_size(start_xy: np.ndarray, end_xy: np.ndarray) -> float:
    """Side of the alignment rectangle before scaling: twice the start→end distance, pixels."""
    return 2.0 * math.hypot(float(end_xy[0] - start_xy[0]), float(end_xy[1] - start_xy[1]))


def roi_from_alignment(start_xy: np.ndarray, end_xy: np.ndarray, scale: float = ROI_SCALE) -> Roi:
    """ROI centred on ``start_xy`` with side ``scale · 2·|end − start|`` (pixels) and the alignment rotation.

    Used with the detector's keypoints 0 (mid-hip) and 1 (body size/rotation point), and in tracking with
    the smoothed auxiliary landmarks 33 and 34.
    """
    return Roi(float(start_xy[0]), float(start_xy[1]), alignment_size(start_xy, end_xy) * scale,
               alignment_rotation(start_xy, end_xy))
