"""Per-user link lengths from a recording of the person standing with the arms down (paper section 3,
step 1): each bone's length is the median over at least 10 frames of the distance between its end joints.

Pixels become metres through the apparent body height: the eyes stand 0.936 H above the heels (Drillis and
Contini, Winter 2009 Fig. 4.1), H the body height the user gives. The person should face the camera (shoulder
and hip widths are measured in the image plane); frames that are not an upright frontal stance with the arms
down are left out, and the reason for each is counted.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from posed.fitting.body import BodyDimensions
from posed.fitting.image2d import distance, down_tilt_deg

MIN_FRAMES = 10
EYE_HEIGHT = 0.936          # eye height / body height (Drillis & Contini)
MAX_LIMB_TILT_DEG = 25.0    # arms and legs within this of vertical in the image
MIN_WIDTH_RATIO = 0.75      # shoulder width / trunk at least this fraction of the nominal ratio (facing)
MAX_DEVIATION = 0.35        # a measured length may differ from the height ratio by at most this fraction
MIN_VISIBILITY = 0.5

_NEEDED = (2, 5, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28, 29, 30)
_MEASURED = ("trunk_m", "shoulder_half_m", "hip_half_m", "upper_arm_m", "forearm_m", "thigh_m", "shank_m")


class CalibrationFailed(ValueError):
    """Not enough usable frames, or implausible lengths; the message says what to record instead."""


@dataclass(frozen=True)
class CalibrationReport:
    dims: BodyDimensions
    frames_used: int
    frames_total: int
    rejected: dict[str, int]
    spread: dict[str, float]   # relative median absolute deviation per measured length


def frame_lengths(lm: np.ndarray, height_m: float) -> tuple[dict[str, float] | None, str]:
    """The measured lengths (metres) of one frame, or None and the reason it is not usable."""
    lm = np.asarray(lm, dtype=np.float64)
    if lm.shape != (33, 5):
        return None, "not a (33, 5) landmark array"
    rows = lm[list(_NEEDED)]
    if not np.isfinite(rows[:, :4]).all() or (rows[:, 3] < MIN_VISIBILITY).any():
        return None, "landmarks missing or not visible"
    p = lm[:, :2]
    for top, mid, end in ((11, 13, 15), (12, 14, 16), (23, 25, 27), (24, 26, 28)):
        if down_tilt_deg(p[top], p[mid]) > MAX_LIMB_TILT_DEG or down_tilt_deg(p[mid], p[end]) > MAX_LIMB_TILT_DEG:
            return None, "not standing with arms and legs straight down"
    eye = 0.5 * (p[2] + p[5])
    heel = 0.5 * (p[29] + p[30])
    if heel[1] - eye[1] <= 0:
        return None, "not upright"
    ppm = (heel[1] - eye[1]) / (EYE_HEIGHT * height_m)
    mid_sh, mid_hp = 0.5 * (p[11] + p[12]), 0.5 * (p[23] + p[24])
    out = {
        "trunk_m": distance(mid_sh, mid_hp) / ppm,
        "shoulder_half_m": distance(p[11], p[12]) / 2 / ppm,
        "hip_half_m": distance(p[23], p[24]) / 2 / ppm,
        "upper_arm_m": 0.5 * (distance(p[11], p[13]) + distance(p[12], p[14])) / ppm,
        "forearm_m": 0.5 * (distance(p[13], p[15]) + distance(p[14], p[16])) / ppm,
        "thigh_m": 0.5 * (distance(p[23], p[25]) + distance(p[24], p[26])) / ppm,
        "shank_m": 0.5 * (distance(p[25], p[27]) + distance(p[26], p[28])) / ppm,
    }
    nominal = BodyDimensions.from_height(height_m)
    if out["shoulder_half_m"] / out["trunk_m"] < MIN_WIDTH_RATIO * nominal.shoulder_half_m / nominal.trunk_m:
        return None, "not facing the camera (shoulders too narrow)"
    return out, ""


def calibrate(frames: Iterable[np.ndarray | None], height_m: float) -> CalibrationReport:
    """Link lengths from the frames of a standing, arms-down, facing-the-camera recording."""
    nominal = BodyDimensions.from_height(height_m)
    used: list[dict[str, float]] = []
    rejected: Counter[str] = Counter()
    total = 0
    for lm in frames:
        total += 1
        if lm is None:
            rejected["no person"] += 1
            continue
        lengths, why = frame_lengths(lm, height_m)
        if lengths is None:
            rejected[why] += 1
        else:
            used.append(lengths)
    if len(used) < MIN_FRAMES:
        why = ", ".join(f"{n} {k}" for k, n in rejected.most_common()) or "no frames"
        raise CalibrationFailed(
            f"only {len(used)} of {total} frames show the person standing upright, facing the camera, arms and "
            f"legs straight down (need {MIN_FRAMES}; rejected: {why}); record again with the whole body in view")
    measured = {k: float(np.median([f[k] for f in used])) for k in _MEASURED}
    spread = {k: float(np.median([abs(f[k] - measured[k]) for f in used]) / measured[k]) for k in _MEASURED}
    for k, v in measured.items():
        ref = getattr(nominal, k)
        if abs(v - ref) > MAX_DEVIATION * ref:
            raise CalibrationFailed(
                f"{k} = {v:.3f} m differs from {ref:.3f} m expected for a {height_m} m person by more than "
                f"{MAX_DEVIATION:.0%}: check --height, and that the person faces the camera with arms down")
    dims = replace(nominal, **measured)
    return CalibrationReport(dims, len(used), total, dict(rejected), spread)
