"""Gravity in camera axes learned from a person standing or walking (``falls.camera_tilt_auto``/``roll_auto``).

Camera axes: x image right, y image down, z away from the camera; gravity ``g`` is a unit vector pointing down.
A standing person is a vertical segment (mid-ankle -> mid-shoulder). Its image line lies in a plane through
the camera centre that holds the vertical, so ``n . g = 0`` for that plane's unit normal ``n`` (normalized
image coordinates: needs the intrinsics, or the configured field of view). Lines from several places in the
image intersect at the vertical vanishing point and fix ``g``; a person seen in one place fixes only the
component across their line (mostly the roll), and the configured gravity ``g0`` fills in the rest.

``g`` minimizes ``sum_i (n_i . g)^2 + PRIOR_WEIGHT |g - g0|^2`` over unit vectors, taken as the eigenvector of
the smallest eigenvalue of ``M = sum n n^T + PRIOR_WEIGHT (I - g0 g0^T)`` (signed along ``g0``). Each line
weighs the time it stands for (``UNIT_S`` = one unit), the prior 0.05 s; the learned gravity is used once 5 s
of standing were seen; the sums decay exponentially, about a minute of standing deep (a robot's camera
moves).

The fit's 3D body axis is not used as a measurement: its depth component (which is what the tilt is) was
biased by 10-20 degrees on the real urfd_dev clips (a level camera). It only selects the frames: a straight
body (legs straight, trunk in line with them — from the fit's joint angles, which do not depend on gravity)
whose axis lies within ``MAX_ANGLE_DEG`` of the current estimate (a person lying straight on the floor is
perpendicular to it and is ignored).
"""

from __future__ import annotations

import math

import numpy as np

# Evidence is counted in time, not frames (a person's lean is the same in consecutive frames, so 30 fps
# is not three times the evidence of 10 fps): one unit = 0.1 s of standing.
UNIT_S = 0.1
PRIOR_WEIGHT = 0.5         # the configured gravity: fills in the directions the lines leave open
# A component (tilt, roll) is learned once the lines hold enough information about it: sum over lines of
# w (n . dg/dangle)^2 >= INFO_MIN. With a person's lean (and a walker's gait) moving the line by ~0.05 rad
# from one 0.1 s unit to the next, 3.0 gives a standard error of ~2 degrees. A person in one place gives the roll (n . dg/droll ~ 1 per line)
# but almost nothing about the tilt (n . dg/dtilt ~ their offset from the image centre / focal length).
INFO_MIN = 3.0
MIN_SAMPLES = 50           # 5 s of standing before the learned gravity replaces the configured one: one
                           # posture's lean persists for seconds (urfd_dev: 2 s in one place left the roll 5° off)
MAX_WEIGHT = 600.0         # exponential forgetting: about the last minute of standing
MAX_ANGLE_DEG = 35.0       # a candidate body axis further than this from the current estimate is ignored


def tilt_roll_deg(g: np.ndarray) -> tuple[float, float]:
    """(tilt down, roll) in degrees of the down vector ``g`` (the inverse of ``gravity_from_tilt``)."""
    g = np.asarray(g, float) / np.linalg.norm(g)
    tilt = math.degrees(math.asin(max(-1.0, min(1.0, float(g[2])))))
    roll = math.degrees(math.atan2(float(g[0]), float(g[1])))
    return tilt, roll


class GravityLearner:
    """Accumulates standing-person evidence; :meth:`estimate` is the learned down vector or None."""

    def __init__(self, prior_g: np.ndarray, min_samples: int = MIN_SAMPLES, max_weight: float = MAX_WEIGHT,
                 prior_weight: float = PRIOR_WEIGHT, max_angle_deg: float = MAX_ANGLE_DEG) -> None:
        g0 = np.asarray(prior_g, float)
        self.prior_g = g0 / np.linalg.norm(g0)
        self.min_samples = min_samples
        self.max_weight = max_weight
        self.prior_weight = prior_weight
        self.cos_max = math.cos(math.radians(max_angle_deg))
        self._m = np.zeros((3, 3))
        self.samples = 0
        self.seconds = 0.0     # standing time seen (s)
        self._weight = 0.0

    def add(self, current_g: np.ndarray, body_up: np.ndarray | None, plane_normal: np.ndarray | None,
            dt: float = UNIT_S) -> bool:
        """One standing frame's evidence (``dt``: seconds since the previous frame, capped at 2 units); False
        (not used) when there is no image line or the body's axis is too far from ``current_g``."""
        if body_up is None or plane_normal is None or not (np.all(np.isfinite(body_up))
                                                          and np.all(np.isfinite(plane_normal))):
            return False
        if float(-body_up @ current_g) < self.cos_max:
            return False
        w = min(max(dt, 0.0) / UNIT_S, 2.0)
        if self._weight >= self.max_weight:
            self._m *= 1.0 - w / self.max_weight
        self._weight = min(self._weight + w, self.max_weight)
        self._m += w * np.outer(plane_normal, plane_normal)
        self.samples += 1
        self.seconds += w * UNIT_S
        return True

    def estimate(self) -> np.ndarray | None:
        """The learned down vector (None before ``min_samples`` units of standing); see :meth:`learned`."""
        if self.seconds < self.min_samples * UNIT_S - 1e-9:
            return None
        g0 = self.prior_g
        _w, v = np.linalg.eigh(self._m + self.prior_weight * (np.eye(3) - np.outer(g0, g0)))
        g = v[:, 0]
        if float(g @ g0) < 0:
            g = -g
        return g / np.linalg.norm(g)

    def learned(self) -> tuple[float | None, float | None]:
        """(tilt, roll) in degrees, each None until the lines hold ``INFO_MIN`` information about it."""
        g = self.estimate()
        if g is None:
            return None, None
        tilt, roll = tilt_roll_deg(g)
        a, b = math.radians(tilt), math.radians(roll)
        d_tilt = np.array([-math.sin(b) * math.sin(a), -math.cos(b) * math.sin(a), math.cos(a)])
        d_roll = np.array([math.cos(b) * math.cos(a), -math.sin(b) * math.cos(a), 0.0])
        info = [float(d @ self._m @ d) / 1.0 for d in (d_tilt, d_roll)]
        return (tilt if info[0] >= INFO_MIN else None), (roll if info[1] >= INFO_MIN else None)

    def state(self) -> dict:
        """What was learned, as JSON-able numbers (:meth:`restore` takes it back)."""
        return {"m": self._m.tolist(), "samples": self.samples, "seconds": self.seconds, "weight": self._weight}

    def restore(self, state: dict) -> None:
        """Take back :meth:`state` (ValueError when it is malformed)."""
        m = np.asarray(state["m"], float)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ValueError("learner matrix must be 3x3 finite numbers")
        self._m = m
        self.samples = int(state["samples"])
        self.seconds = float(state["seconds"])
        self._weight = float(state["weight"])
