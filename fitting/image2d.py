"""Plain-float geometry of landmark positions in the image (pixels or normalized units, x right, y down):
the distance of two points and the angle of a segment from the image's downward vertical. Shared by the
calibration (``posed calibrate``) and the proportion learner of video mode."""

from __future__ import annotations

import math


def distance(a, b) -> float:
    """Distance of the image points ``a`` and ``b`` (two-element sequences)."""
    return float(math.hypot(a[0] - b[0], a[1] - b[1]))


def down_tilt_deg(top, bottom) -> float:
    """Angle of ``top -> bottom`` from the image's downward vertical, degrees: 0 = straight down, 180 = straight
    up (and for coincident points)."""
    dx, dy = float(bottom[0] - top[0]), float(bottom[1] - top[1])
    return math.degrees(math.atan2(abs(dx), dy)) if (dx or dy) else 180.0
