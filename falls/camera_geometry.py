"""The camera geometry the fall detector judges with: gravity, the floor and the person's standing height.

Camera axes: x image right, y image down, z away from the camera; gravity ``g`` is a unit vector pointing
down. Heights are metres along ``g``.

* **Gravity**, in this order: the IMU's (``set_imu``: a RealSense accelerometer, ``falls.imu_gravity``), else
  the tilt and roll learned from a standing person where ``camera_tilt_auto``/``camera_roll_auto`` and once
  learned (:mod:`falls.geometry`), else the configured ``camera_tilt_deg``/``camera_roll_deg``. A new gravity
  is applied only when it moved more than ``GRAVITY_STEP_DEG`` from the one in use; heights measured along
  the old one are then forgotten (the floor and the standing height are learned again) and the caller is
  told, so it can forget the motion too. Except from one IMU reading to the next: the accelerometer measures
  the camera's own rotation (a robot turning its head), which moves neither the floor nor the camera's
  height above it, and each frame's heights are measured along that frame's true gravity, so they stay
  comparable: each reading is used as it comes, and nothing is forgotten.
* **Floor**: its distance below the camera, learned from the ankles of a person standing upright
  (``learn_floor``; used after ``FLOOR_MIN_WEIGHT`` observations), else ``camera_height_m`` (0: unknown).
* **Standing pelvis height**: learned the same way (after ``STAND_MIN_WEIGHT`` observations).
"""

from __future__ import annotations

import math

import numpy as np

from posed.falls.config import FallsConfig
from posed.falls.features import gravity_from_tilt
from posed.falls.geometry import GravityLearner, tilt_roll_deg

GRAVITY_STEP_DEG = 1.0   # a learned gravity is applied when it moved this far from the one in use
FLOOR_MIN_WEIGHT = 5.0   # standing observations before the learned floor replaces the configured one
STAND_MIN_WEIGHT = 3.0   # ... before the learned standing pelvis height is used
EMA_MAX_WEIGHT = 30.0    # running means become exponential averages over about this many observations


class CameraGeometry:
    """Gravity, floor and standing height in use, and where each comes from (module doc)."""

    def __init__(self, cfg: FallsConfig) -> None:
        self.cfg = cfg
        self._gravity_cfg = gravity_from_tilt(cfg.camera_tilt_deg, cfg.camera_roll_deg)
        self.gravity = self._gravity_cfg           # down, camera axes, unit
        self.roll_deg = cfg.camera_roll_deg       # of the gravity in use
        self._gravity_imu: np.ndarray | None = None
        self._learner = GravityLearner(self._gravity_cfg) if (cfg.camera_tilt_auto or cfg.camera_roll_auto) else None
        self._floor_cfg = cfg.camera_height_m if cfg.camera_height_m > 0 else None
        self._floor_learned: float | None = None
        self._floor_weight = 0.0
        self._stand: float | None = None          # standing pelvis height (m), learned
        self._stand_weight = 0.0

    # ------------------------------------------------------------------ gravity

    def set_imu(self, down_camera: np.ndarray | None) -> bool:
        """Gravity from an IMU, a down vector in camera axes (any length); None returns to the configured
        (or learned) tilt and roll; a broken reading (not finite, zero) changes nothing. True when the
        gravity in use changed."""
        if down_camera is None:
            self._gravity_imu = None
        else:
            g = np.asarray(down_camera, float)
            n = float(np.linalg.norm(g))
            if not (np.all(np.isfinite(g)) and n > 1e-9):
                return False
            if self._gravity_imu is not None:   # the camera turned (or the reading moved): nothing to forget
                self._gravity_imu = g / n
                self._use(self._gravity_imu)
                return False
            self._gravity_imu = g / n
        return self._refresh()

    def learn(self, up_c: np.ndarray, axis_plane_c: np.ndarray, dt: float) -> bool:
        """A straight standing body seen for ``dt`` seconds (:meth:`falls.geometry.GravityLearner.add`); ignored
        with an IMU or without ``*_auto``. True when the gravity in use changed."""
        if self._learner is None or self._gravity_imu is not None:
            return False
        return self._learner.add(self.gravity, up_c, axis_plane_c, dt) and self._refresh()

    def _refresh(self) -> bool:
        cfg = self.cfg
        if self._gravity_imu is not None:
            g = self._gravity_imu
        else:
            tilt, roll = self._learner.learned() if self._learner is not None else (None, None)
            g = gravity_from_tilt(tilt if cfg.camera_tilt_auto and tilt is not None else cfg.camera_tilt_deg,
                                  roll if cfg.camera_roll_auto and roll is not None else cfg.camera_roll_deg)
        if float(g @ self.gravity) >= math.cos(math.radians(GRAVITY_STEP_DEG)):
            return False  # the learned estimate drifts by less than a step: keep the gravity in use
        self._floor_learned, self._floor_weight = None, 0.0
        self._stand, self._stand_weight = None, 0.0
        self._use(g)
        return True

    def _use(self, g: np.ndarray) -> None:
        self.gravity = g
        self.roll_deg = tilt_roll_deg(g)[1]

    # ------------------------------------------------------------------ floor and standing height

    @property
    def floor_below_camera(self) -> float | None:
        """The floor's distance below the camera along gravity (m), learned or configured; None unknown."""
        if self._floor_learned is not None and self._floor_weight >= FLOOR_MIN_WEIGHT:
            return self._floor_learned
        return self._floor_cfg

    def observe_floor(self, below_camera_m: float) -> None:
        """The floor seen below the feet of a person standing upright (m below the camera)."""
        if self.cfg.learn_floor:
            self._floor_learned, self._floor_weight = _ema(self._floor_learned, self._floor_weight, below_camera_m)

    def observe_standing_pelvis(self, height_m: float) -> None:
        """The pelvis height above the floor of a person standing upright (m)."""
        self._stand, self._stand_weight = _ema(self._stand, self._stand_weight, height_m)

    def standing_pelvis(self) -> float | None:
        """The learned standing pelvis height (m), or None until it is known."""
        return self._stand if self._stand is not None and self._stand_weight >= STAND_MIN_WEIGHT else None

    # ------------------------------------------------------------------ report

    def summary(self) -> dict:
        """Tilt and roll (deg), floor below the camera (m, None unknown), where each comes from (config,
        learned, imu; height: learned, config, unknown) and the seconds of standing the learner has seen."""
        tilt, roll = tilt_roll_deg(self.gravity)
        l_tilt, l_roll = self._learner.learned() if self._learner is not None else (None, None)
        src = "imu" if self._gravity_imu is not None else None
        learned_floor = self._floor_learned is not None and self._floor_weight >= FLOOR_MIN_WEIGHT
        return {"tilt_deg": tilt, "roll_deg": roll, "floor_below_camera_m": self.floor_below_camera,
                "tilt_from": src or ("learned" if l_tilt is not None and self.cfg.camera_tilt_auto else "config"),
                "roll_from": src or ("learned" if l_roll is not None and self.cfg.camera_roll_auto else "config"),
                "height_from": "learned" if learned_floor else ("config" if self._floor_cfg is not None else "unknown"),
                "standing_s": 0.0 if self._learner is None else round(self._learner.seconds, 2)}


def _ema(value: float | None, weight: float, obs: float, max_weight: float = EMA_MAX_WEIGHT) -> tuple[float, float]:
    """Running mean that becomes an exponential average after ``max_weight`` observations."""
    if value is None or not math.isfinite(value):
        return obs, 1.0
    weight = min(weight + 1.0, max_weight)
    return value + (obs - value) / weight, weight
