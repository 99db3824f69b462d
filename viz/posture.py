"""Posture over a day, from the stored joint angles alone (the history keeps angles, not positions).

Each stored sample's angles are put back on the model (``fitting.Pose`` -> ``fitting.joints_3d``, a 1.6 m
body: only directions are used, so the size does not matter) and two inclinations from the vertical are
measured in the camera frame against the vertical: the down each sample was fitted against (an IMU's, a
depth floor's, ...: stored with it in the history), else the camera's down when the report knows it (a measured
mount's tilt and roll, or what the fall detector learned of the camera: ``down``), else the camera taken as
level:

* trunk: mid-hip -> mid-shoulder;  thigh: hip -> knee (the more inclined of the two).

and the sample is classified as

* **lying**   — trunk more than ``LYING_TRUNK_DEG`` (60, the fall detector's ``lying_trunk_deg``) from vertical;
* **sitting** — trunk within it, and a thigh more than ``SITTING_THIGH_DEG`` (50) from vertical (thighs
  roughly horizontal: on a chair, a bed's edge, squatting, kneeling);
* **standing** — trunk and thighs near vertical (standing and walking).

Each sample counts for the time until the next one, at most ``max_step_s``. A sample whose torso was not
measured (fitting.measured), or whose trunk is up while neither thigh was measured, has no posture. The rest
of the day is told apart by the minutes posed watched (``daemon.history.watched``, ``viz.report``): a person
in view without a measured posture, nobody in view, posed not watching, or not yet.

Limits, said plainly: the classification trusts the fit, so a fit with a wrong depth mirror (a thigh flipped
toward the camera) can turn standing into sitting for a moment; a deep squat or kneeling counts as sitting;
someone lying on a sofa seen end-on (trunk along the camera's axis) is correctly "lying", but without the
camera's down a trunk lying along the view of a camera tilted down reads less inclined by the tilt. A sit-to-stand transition is
counted when at least ``MIN_RUN_S`` of sitting is followed within ``MAX_SWITCH_S`` by at least
``MIN_RUN_S`` of standing. A walking bout is at least ``WALK_MIN_S`` of standing in which the two hip
flexions swap sign against each other (left ahead, right ahead) at least ``WALK_MIN_SWAPS`` times with a
difference above ``WALK_SWING_DEG``: stepping in place counts, and shuffling with little hip swing is missed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

LYING_TRUNK_DEG = 60.0
SITTING_THIGH_DEG = 50.0
MIN_RUN_S = 1.0
MAX_SWITCH_S = 4.0
WALK_MIN_S = 3.0
WALK_MIN_SWAPS = 3
WALK_SWING_DEG = 10.0
POSTURES = ("standing", "sitting", "lying")
_UP = np.array([0.0, -1.0, 0.0])     # up in the camera frame (y image down), the camera level


@lru_cache(maxsize=1)
def _dims():
    from posed.fitting import BodyDimensions

    return BodyDimensions.from_height(1.6)


def valid_down(down) -> np.ndarray | None:
    """``down`` (a fit result's or a history sample's gravity, camera axes, any length) as an array, or None
    when it is not three finite numbers, not all 0."""
    try:
        d = np.asarray(down, float)
    except (TypeError, ValueError):
        return None
    return d if d.shape == (3,) and np.isfinite(d).all() and np.linalg.norm(d) > 0 else None


def incline_deg(v: np.ndarray, down=None) -> float:
    """The angle of camera-frame vector ``v`` from the vertical, degrees: against ``down`` (a
    :func:`valid_down`), or the level camera's when None; NaN for a zero ``v``."""
    up = _UP if down is None else -np.asarray(down, float) / np.linalg.norm(down)
    n = float(np.linalg.norm(v))
    return float(np.degrees(np.arccos(np.clip(v @ up / n, -1.0, 1.0)))) if n > 0 else float("nan")


def method_text(down=None) -> list[str]:
    """The rules above in plain sentences, for the report (numbers from this module's constants); ``down``:
    the camera's down for the samples fitted without one (None: the camera taken as level)."""
    return [
        "Posture is worked out from the stored joint angles alone: each sample's angles are put back on the "
        "body model, and the trunk (hips to shoulders) and thigh (hip to knee) inclinations from the vertical "
        "are measured: against the direction of gravity the fit used for that sample (a camera's "
        "accelerometer, the floor in a depth image, a measured mount), stored with it; for a sample fitted "
        "without one, "
        + ("the camera taken as level." if down is None else
           f"against the camera's down as it is known now ({_tilt_text(down)})."),
        f"Lying: the trunk more than {LYING_TRUNK_DEG:.0f} degrees from vertical. Sitting: the trunk within "
        f"that and a thigh more than {SITTING_THIGH_DEG:.0f} degrees from vertical (on a chair, a bed's edge, "
        "squatting, kneeling). Standing: trunk and thighs near vertical (standing and walking).",
        "Each sample counts for the time until the next one (at most a few sampling periods). A sample has no "
        "posture when the camera did not see both shoulders and both hips, or when the trunk is up and neither "
        "thigh was seen (sitting and standing then look alike).",
        f"A sit-to-stand transition: at least {MIN_RUN_S:.0f} s sitting followed within {MAX_SWITCH_S:.0f} s by "
        f"at least {MIN_RUN_S:.0f} s standing. A walking bout: at least {WALK_MIN_S:.0f} s standing in which "
        f"the two hip flexions swap which is ahead at least {WALK_MIN_SWAPS} times by more than "
        f"{WALK_SWING_DEG:.0f} degrees.",
        "Limits: it trusts the fit, so a fit with a limb mirrored in depth can turn standing into sitting for "
        "a moment; a deep squat or kneeling counts as sitting; stepping in place counts as walking and "
        "shuffling with little hip swing is missed; "
        + ("a tilted camera (not level) biases every inclination of a sample fitted without gravity." if down is None
           else "a sample fitted without gravity is measured against the camera's down as it is known now."),
    ]


def _tilt_text(down) -> str:
    from posed.falls.geometry import tilt_roll_deg

    tilt, roll = tilt_roll_deg(down)
    return f"looking {tilt:.0f} degrees down, rolled {roll:.0f}"


def inclinations(angles: Mapping[str, float], down=None) -> tuple[float, float]:
    """(trunk, steeper thigh) inclination from the vertical in degrees for one sample's angles (joint angles
    by ``fitting.JOINT_ANGLE_NAMES`` and body angles ``theta_bd``..; missing joint angles 0); ``down``: the
    camera's down (camera axes; None: the camera taken as level)."""
    from posed.fitting import BODY_ANGLE_NAMES, JOINT_ANGLE_NAMES, Pose, joints_3d

    joints = {k: float(v) for k, v in angles.items() if k in JOINT_ANGLE_NAMES and np.isfinite(v)}
    body = {k: float(angles.get(k, 0.0)) for k in BODY_ANGLE_NAMES}
    j = {k: np.asarray(v) for k, v in joints_3d(Pose(joints, **body), _dims()).items()}
    trunk = incline_deg((j["left_shoulder"] + j["right_shoulder"]) / 2 - j["mid_hip"], down)
    thigh = max(incline_deg(j["left_hip"] - j["left_knee"], down), incline_deg(j["right_hip"] - j["right_knee"], down))
    return trunk, thigh


def classify(angles: Mapping[str, float], down=None) -> str | None:
    """``standing``, ``sitting`` or ``lying`` for one sample; None when the body angles are unknown (the
    torso not measured), or when the trunk is up and neither thigh was measured (sitting and standing then
    look the same)."""
    if any(not np.isfinite(angles.get(k, np.nan)) for k in ("theta_bd", "phi_bd", "psi_bd")):
        return None
    trunk, thigh = inclinations(angles, down)
    if trunk > LYING_TRUNK_DEG:
        return "lying"
    if not any(np.isfinite(angles.get(k, np.nan)) for k in ("theta_hp_l", "theta_hp_r")):
        return None
    return "sitting" if thigh > SITTING_THIGH_DEG else "standing"


@dataclass(frozen=True)
class Run:
    """A stretch of one posture: ``start``..``end`` (seconds, the series' clock)."""

    posture: str
    start: float
    end: float

    @property
    def seconds(self) -> float:
        return self.end - self.start


@dataclass(frozen=True)
class DaySummary:
    seconds: dict[str, float]           # standing/sitting/lying/not seen -> seconds
    runs: list[Run]
    sit_to_stand: int
    walking_bouts: list[Run]


def summarise(time: np.ndarray, angles: Mapping[str, np.ndarray], span: tuple[float, float],
              max_step_s: float = 1.0, down=None) -> DaySummary:
    """The posture summary of samples at ``time`` (seconds, increasing) with their ``angles`` (name -> array,
    NaN unknown) over ``span`` (start, end) of the day; each sample measured against the down it was fitted
    against (``down_x``, ``down_y``, ``down_z`` in ``angles``, the history's), else ``down`` (the camera's;
    None: level)."""
    t = np.asarray(time, float)
    n = len(t)
    labels = [classify(sample, _sample_down(sample, down))
              for sample in ({k: float(v[i]) for k, v in angles.items()} for i in range(n))]
    seconds = dict.fromkeys((*POSTURES, "not seen"), 0.0)
    runs: list[Run] = []
    for i in range(n):
        end = min(t[i + 1] if i + 1 < n else t[i] + max_step_s, t[i] + max_step_s)
        lab = labels[i]
        if lab is None:
            continue
        seconds[lab] += end - t[i]
        if runs and runs[-1].posture == lab and t[i] - runs[-1].end <= max_step_s:
            runs[-1] = Run(lab, runs[-1].start, end)
        else:
            runs.append(Run(lab, float(t[i]), float(end)))
    seconds["not seen"] = max(0.0, (span[1] - span[0]) - sum(seconds[p] for p in POSTURES))
    sts = sum(1 for a, b in zip(runs, runs[1:], strict=False)
              if a.posture == "sitting" and b.posture == "standing" and a.seconds >= MIN_RUN_S
              and b.seconds >= MIN_RUN_S and b.start - a.end <= MAX_SWITCH_S)
    return DaySummary(seconds, runs, sts, _walking(t, angles, runs))


def _sample_down(sample: Mapping[str, float], down):
    """The down a sample was fitted against (its ``down_x``, ``down_y``, ``down_z``: the history's
    ``DOWN_COLUMNS``), else ``down``."""
    d = valid_down([sample.get(k, np.nan) for k in ("down_x", "down_y", "down_z")])
    return d if d is not None else down


def _walking(t: np.ndarray, angles: Mapping[str, np.ndarray], runs: list[Run]) -> list[Run]:
    left, right = angles.get("theta_hp_l"), angles.get("theta_hp_r")
    if left is None or right is None:
        return []
    diff = np.asarray(left, float) - np.asarray(right, float)
    bouts = []
    for r in runs:
        if r.posture != "standing" or r.seconds < WALK_MIN_S:
            continue
        sel = (t >= r.start) & (t < r.end) & np.isfinite(diff)
        d = diff[sel]
        signs = np.sign(d[np.abs(d) > WALK_SWING_DEG])
        swaps = int(np.count_nonzero(np.diff(signs) != 0)) if len(signs) > 1 else 0
        if swaps >= WALK_MIN_SWAPS:
            bouts.append(r)
    return bouts
