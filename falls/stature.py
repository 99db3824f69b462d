"""A standing person's stature from one image, by ground-plane metrology (no depth, no assumed body size).

With the camera's gravity ``d`` (unit, camera axes, down) and its height ``h`` above the floor known (measured:
the depth floor, or a configured mount marked measured), the ray through the mid-ankle pixel meets the plane
where the ankles stand, and the mid-shoulder seen above them sits on a vertical line through that point: two
rays and a vertical fix the person's height in metres, whatever the body size the fit assumed.

Anthropometric ratios (Drillis and Contini 1966, as tabulated in Winter, *Biomechanics and Motor Control of
Human Movement*, 4th ed., Fig. 4.1): ankle height ``ANKLE_OF_STATURE`` = 0.039 and shoulder (acromion) height
``SHOULDER_OF_STATURE`` = 0.818 of the stature ``H``. Unknowns ``H`` and the shoulder's distance ``t`` along
its ray, from

    A = (h - 0.039 H) / (d . r_a) * r_a                 (the mid-ankle on its ray, 0.039 H above the floor)
    A - (0.818 - 0.039) H d = t r_s                      (the mid-shoulder straight above it)

three equations in two unknowns, solved by least squares; the residual (metres) says how far the body is from
a vertical line (a lean, a step). Only frames of a person standing upright should be offered (the caller's
job: the fall detector's straight-body frames with the trunk near vertical).

Error: a tilt error of 1 deg moves the ankle point by about distance x 1.7 % (5 cm at 3 m) and the stature by
a similar share; a camera height error of 5 % scales the stature by 5 %. Units: pixels, metres.
"""

from __future__ import annotations

import numpy as np

from posed.camera_model import Intrinsics

ANKLE_OF_STATURE = 0.039
SHOULDER_OF_STATURE = 0.818
STATURE_RANGE_M = (0.9, 2.3)     # outside: not a standing adult seen whole (a wrong frame)
MAX_LEAN_M = 0.15                # least-squares residual above this: not standing on a vertical line
SHOULDERS, ANKLES = (11, 12), (27, 28)


def stature_m(landmarks: np.ndarray, camera: Intrinsics, down_c: np.ndarray, floor_below_m: float,
              min_visibility: float = 0.5) -> float | None:
    """The stature (m) of the person of ``landmarks`` (33 x >= 4, pixels of ``camera``'s image) standing on the
    floor ``floor_below_m`` below the camera along ``down_c``; None when it cannot be measured (a shoulder or
    an ankle not seen, the ankles above the horizon, a result out of ``STATURE_RANGE_M`` or leaning)."""
    lm = np.asarray(landmarks, float)
    if lm.ndim != 2 or lm.shape[0] < 29 or not floor_below_m or floor_below_m <= 0:
        return None
    idx = SHOULDERS + ANKLES
    pts = lm[list(idx)]
    if not np.all(np.isfinite(pts[:, :2])):
        return None
    if lm.shape[1] > 3 and np.any(pts[:, 3] < min_visibility):
        return None
    d = np.asarray(down_c, float)
    d = d / np.linalg.norm(d)
    r_s = _ray(0.5 * (pts[0, :2] + pts[1, :2]), camera)
    r_a = _ray(0.5 * (pts[2, :2] + pts[3, :2]), camera)
    da = float(d @ r_a)
    if da < 0.02:                     # the ankles at or above the horizon: their ray never meets the floor
        return None
    col_h = ANKLE_OF_STATURE / da * r_a + (SHOULDER_OF_STATURE - ANKLE_OF_STATURE) * d
    m = np.stack([col_h, r_s], axis=1)
    b = floor_below_m / da * r_a
    (h, t), *_ = np.linalg.lstsq(m, b, rcond=None)
    if t <= 0 or not STATURE_RANGE_M[0] <= h <= STATURE_RANGE_M[1]:
        return None
    if float(np.linalg.norm(m @ np.array([h, t]) - b)) > MAX_LEAN_M:
        return None
    return float(h)


def _ray(px: np.ndarray, camera: Intrinsics) -> np.ndarray:
    return np.array([(px[0] - camera.cx) / camera.fx, (px[1] - camera.cy) / camera.fy, 1.0])
