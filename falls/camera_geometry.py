"""The camera geometry the fall detector judges with: gravity, the floor and the person's standing height.

Camera axes: x image right, y image down, z away from the camera; gravity ``g`` is a unit vector pointing
down. Heights are metres along ``g``.

* **Gravity**, in this order: the robot's (``set_robot``: the camera's pose from the robot's own kinematics,
  ``falls.camera_mount_from_bus``), else the IMU's (``set_imu``: a RealSense accelerometer, ``falls.imu_gravity``), else
  the floor plane measured in the depth image (``set_depth_floor``: a RealSense, ``falls.floor_from_depth``,
  :mod:`falls.floor_plane`), else the tilt and roll learned from a standing person where ``camera_tilt_auto``/``camera_roll_auto`` and once
  learned (:mod:`falls.geometry`), else the configured ``camera_tilt_deg``/``camera_roll_deg``. A new gravity
  is applied only when it moved more than ``GRAVITY_STEP_DEG`` from the one in use; heights measured along
  the old one are then forgotten (the floor and the standing height are learned again) and the caller is
  told, so it can forget the motion too. Except from one IMU reading to the next: the accelerometer measures
  the camera's own rotation (a robot turning its head), which moves neither the floor nor the camera's
  height above it, and each frame's heights are measured along that frame's true gravity, so they stay
  comparable: each reading is used as it comes, and nothing is forgotten.
* **Floor**: the height the robot gives with its pose, else the plane measured in the depth image (its
  distance along the gravity in use), else its distance
  below the camera learned from the ankles of a person standing or sitting upright, or from the stance foot of
  one walking upright (``learn_floor``; used after ``FLOOR_MIN_WEIGHT`` observations), else ``camera_height_m``
  (0: unknown). A height in true metres (the robot's, a configured one marked measured) is judged in the fit's
  metres once the feet of people standing upright gave their ratio (:meth:`CameraGeometry.fit_scale`; not with a
  depth floor, whose fit is metric).
* **Standing pelvis height**: learned from a person standing upright (after ``STAND_MIN_WEIGHT``
  observations); moved with the floor when the learned floor replaces the configured one
  (``shift_standing_pelvis``).
* **Trust** (``camera_geometry``): configured values that were measured for this mount are used as they are.
  A guess (a freshly started daemon with the default tilt 0 and height 1 m) is checked: gravity then comes from the
  person's own standing body once it contradicts the guess (the fit's mid-ankle -> mid-shoulder axis of
  straight-body frames, averaged over time; ``BODY_REJECT_DEG``), or once the guess puts the feet of the
  bodies seen at or above the camera (no camera above a floor sees the feet of someone on it there), and a
  guessed height is then dropped too, with the standing height measured along the guess: heights above the
  floor count once the floor was learned from their feet (before that the lowest fitted joint stands in for
  the floor). With ``auto`` each value is trusted on its own once set
  (``tilt_measured``: the tilt or roll differs from 0; ``measured``: any of the three differs from its
  default): a height set with the tilt left at 0 is kept while the tilt is checked against the body.
  :meth:`CameraGeometry.used` says which sources a frame was judged with.
* **Measured beats guessed**: a floor seen in the depth image is a measurement of this mount, now: it ranks
  above everything learned from people and above the configured values (even ``measured`` ones: a robot's
  camera moves). The IMU still gives the gravity when there is one (it follows the camera from frame to frame;
  the depth floor is refreshed about once a second, with the IMU's gravity as its prior); the depth floor then
  gives the height. The depth floor is live: it is not kept across restarts, and the caller forgets it
  (``set_depth_floor(None)``) when it grows old.
* **The robot knows best**: a robot that moves its camera (pans and tilts its head, raises a mast) knows the
  camera's pose from its kinematics at every moment; it ranks above everything (the IMU included) for the
  gravity, and its height above everything for the floor. From one robot pose to the next nothing is forgotten
  (as from one IMU reading to the next: each frame's heights are measured along that frame's gravity, above
  that frame's floor). While it is in force, nothing is learned from people about the camera (the tilt
  learner, the body's axis: in camera axes, which the robot moves) and :meth:`CameraGeometry.state` keeps
  what was learned before it; when it ends, that is taken back as it was (``set_robot(None)``).
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
# Gravity from the standing body while the configured geometry is a guess. A standing person's body axis is
# within a few degrees of vertical (postural sway), but the fit's depth component of that axis is poor: on
# urfd_dev (a level camera) the per-clip mean of the fit's straight-body axis read a tilt of -1 to 20 deg
# (median 8) and roll -4 to 17 deg. So the guess is kept unless, after BODY_MIN_S of straight-body frames,
# the body contradicts it by more than BODY_REJECT_DEG (about twice that spread: a level guess on a wall camera
# 30-45 deg down is rejected, a level camera's own body axis is not), or the guess puts the feet of those
# bodies at or above the camera (a camera 18-22 deg down with the person 4 m away: the body axis may read
# half the tilt, but no camera above a floor sees the feet of someone on it above itself); then the body's
# gravity is used and refined in steps of BODY_STEP_DEG, the floor seen under the feet re-projected; from
# then on only bodies within upright_trunk_deg of it refine it (a fall's first half second is a straight body).
BODY_MIN_S = 1.0
BODY_REJECT_DEG = 20.0
BODY_MAX_S = 30.0
BODY_STEP_DEG = 3.0
SEATED_WEIGHT = 0.5                # a seated trunk leans ~15-20 deg back or forward: half the weight
BODY_MAX_FROM_CONFIG_DEG = 60.0    # a mount guessed level can be tilted this far (wall cameras: 30-45 deg down)
BODY_MAX_FROM_CURRENT_DEG = 45.0   # a straight body further than this from the gravity in use is not standing
STATE_VERSION = 1
# the configured values a kept state was learned under: when one changes, the state is not taken back
STATE_CONFIG_KEYS = ("camera_tilt_deg", "camera_roll_deg", "camera_height_m", "camera_geometry", "camera_tilt_auto",
                     "camera_roll_auto", "learn_floor", "camera_hfov_deg")
DEFAULT_GEOMETRY = (0.0, 0.0, 1.0)   # FallsConfig's camera_tilt_deg, camera_roll_deg, camera_height_m


class CameraGeometry:
    """Gravity, floor and standing height in use, and where each comes from (module doc)."""

    def __init__(self, cfg: FallsConfig) -> None:
        self.cfg = cfg
        self._gravity_cfg = gravity_from_tilt(cfg.camera_tilt_deg, cfg.camera_roll_deg)
        self.gravity = self._gravity_cfg           # down, camera axes, unit
        self.roll_deg = cfg.camera_roll_deg       # of the gravity in use
        self._gravity_imu: np.ndarray | None = None
        self._robot: tuple[np.ndarray, float | None, dict] | None = None   # down (unit), height or None, evidence
        self._before_robot: dict | None = None      # what was learned from people when the robot took over
        self._depth: tuple[np.ndarray, float, dict] | None = None   # floor plane: down (unit), height, evidence
        self._learner = GravityLearner(self._gravity_cfg) if (cfg.camera_tilt_auto or cfg.camera_roll_auto) else None
        self._floor_cfg = cfg.camera_height_m if cfg.camera_height_m > 0 else None
        self._floor_learned: float | None = None
        self._floor_weight = 0.0
        self._stand: float | None = None          # standing pelvis height (m), learned
        self._stand_weight = 0.0
        self._scale: float | None = None          # the fit's metres per true metre, learned (fit_scale)
        self._scale_weight = 0.0
        mode = cfg.camera_geometry
        self.measured = mode == "measured" or (mode == "auto" and (cfg.camera_tilt_deg, cfg.camera_roll_deg,
                                                                   cfg.camera_height_m) != DEFAULT_GEOMETRY)
        # the tilt and roll alone: a height set with them left at 0 is trusted, they are still checked (body)
        self.tilt_measured = mode == "measured" or (mode == "auto" and (cfg.camera_tilt_deg, cfg.camera_roll_deg)
                                                    != DEFAULT_GEOMETRY[:2])
        self._floor_point: np.ndarray | None = None   # a point on the learned floor, camera axes
        self._body_floor_sum = np.zeros(3)         # time-weighted sum of floor points under straight bodies
        self._body_floor_w = 0.0
        self._body_sum = np.zeros(3)               # time-weighted sum of standing body axes (down), camera axes
        self._body_s = 0.0                         # seconds of straight body behind it
        self._gravity_from = "config"
        self.restored = False                      # taken back from an earlier run (restore)

    # ------------------------------------------------------------------ gravity

    def set_robot(self, down_camera: np.ndarray | None, height_m: float | None = None,
                  evidence: dict | None = None) -> bool:
        """The camera's pose from the robot: ``down_camera`` gravity in camera axes (any length), ``height_m`` the
        optical centre above the floor (m) or None (the floor then comes from the other sources), ``evidence``
        (its age, source, ...: shown in the summary and in each event's geometry). It gives the gravity ahead of
        the IMU and everything else, and its height the floor. None forgets it and takes back what was learned
        from people before it. Raises ValueError for a broken pose (not finite, a zero down, a height not above
        0), changing nothing. True when the robot took over or let go (another gravity or floor: heights are
        not comparable across it); False from one robot pose to the next."""
        if down_camera is None:
            if self._robot is None:
                return False
            self._robot = None
            before, self._before_robot = self._before_robot, None
            # what was seen meanwhile was measured along the robot's gravity and above its floor: not kept
            self._floor_learned, self._floor_weight, self._floor_point = None, 0.0, None
            self._stand, self._stand_weight = None, 0.0
            self._scale, self._scale_weight = None, 0.0   # learned against the robot's height
            restored = self.restored
            if before is None or self.restore(before) is not None:   # the same configured values: as it was
                self._refresh()
            self.restored = restored
            return True                       # another gravity or floor: the motion is not comparable
        g = np.asarray(down_camera, float)
        n = float(np.linalg.norm(g)) if g.shape == (3,) and np.all(np.isfinite(g)) else 0.0
        if n < 1e-9:
            raise ValueError(f"the robot's down must be three finite numbers, not all 0; got {down_camera!r}")
        h = None if height_m is None else float(height_m)
        if h is not None and not (math.isfinite(h) and h > 0.0):
            raise ValueError(f"the camera's height above the floor must be a positive number of metres or None, "
                             f"got {height_m!r}")
        if self._robot is not None:           # the robot moved its camera: nothing to forget
            self._robot = (g / n, h, dict(evidence or {}))
            self._use(self._robot[0])
            return False
        self._before_robot = self.state()
        self._scale, self._scale_weight = None, 0.0   # learned against another height: learned again
        self._robot = (g / n, h, dict(evidence or {}))
        changed = self._refresh()
        self._use(self._robot[0])             # as it comes, even within a step of the gravity in use
        return changed or h is not None       # a new floor: heights not comparable either

    @property
    def robot_in_force(self) -> bool:
        """Whether the robot gives the camera's pose now (:meth:`set_robot`)."""
        return self._robot is not None

    def set_imu(self, down_camera: np.ndarray | None) -> bool:
        """Gravity from an IMU, a down vector in camera axes (any length); None returns to the configured
        (or learned) tilt and roll; a broken reading (not finite, zero) changes nothing. True when the
        gravity in use changed (never while the robot gives it)."""
        if down_camera is None:
            self._gravity_imu = None
        else:
            g = np.asarray(down_camera, float)
            n = float(np.linalg.norm(g))
            if not (np.all(np.isfinite(g)) and n > 1e-9):
                return False
            if self._gravity_imu is not None:   # the camera turned (or the reading moved): nothing to forget
                self._gravity_imu = g / n
                if self._robot is None:
                    self._use(self._gravity_imu)
                return False
            self._gravity_imu = g / n
        return self._refresh()

    def set_depth_floor(self, down_camera: np.ndarray | None, height_m: float = 0.0,
                        evidence: dict | None = None) -> bool:
        """The floor plane measured in the depth image (:func:`falls.floor_plane.fit_floor`): its down normal
        (camera axes, any length) and the camera's distance to it (m), with ``evidence`` (inliers, residual,
        age, ...: shown in the summary and in each event's geometry). It gives the gravity unless an IMU does,
        and the floor ahead of anything learned or configured. None forgets it (back to the other sources).
        Raises ValueError for a broken plane (not finite, a zero normal, a height not above 0), changing
        nothing. True when the gravity in use changed."""
        if down_camera is None:
            if self._depth is None:
                return False
            self._depth = None
            return self._gravity_imu is None and self._robot is None and self._refresh()
        n = np.asarray(down_camera, float)
        norm = float(np.linalg.norm(n)) if n.shape == (3,) and np.all(np.isfinite(n)) else 0.0
        h = float(height_m)
        if norm < 1e-9:
            raise ValueError(f"the floor's down normal must be three finite numbers, not all 0; got {down_camera!r}")
        if not (math.isfinite(h) and h > 0.0):
            raise ValueError(f"the camera's height above the floor must be a positive number of metres, got {height_m!r}")
        self._depth = (n / norm, h, dict(evidence or {}))
        return self._gravity_imu is None and self._robot is None and self._refresh()

    def learn(self, up_c: np.ndarray, axis_plane_c: np.ndarray, dt: float) -> bool:
        """A straight standing body seen for ``dt`` seconds (:meth:`falls.geometry.GravityLearner.add`); ignored
        with an IMU, while the robot gives the pose, or without ``*_auto``. True when the gravity in use changed."""
        if self._learner is None or self._gravity_imu is not None or self._robot is not None:
            return False
        return self._learner.add(self.gravity, up_c, axis_plane_c, dt) and self._refresh()

    def observe_body_axis(self, up_c: np.ndarray | None, dt: float, ankles_c: np.ndarray | None = None,
                          ankle_height_m: float = 0.0) -> bool:
        """A straight standing body's up axis (unit, camera axes) seen for ``dt`` seconds: gravity while the
        configured geometry is a guess and neither an IMU nor the learned tilt gives it; its ankles (camera axes)
        and their height above the floor give a point on the floor along that axis, used if the guess is
        rejected before the floor was learned; nothing while the robot gives the pose. True when the gravity in
        use changed."""
        if self.tilt_measured or self._robot is not None or up_c is None or not np.all(np.isfinite(up_c)):
            return False
        if ankles_c is not None and np.all(np.isfinite(ankles_c)):
            w = min(max(dt, 0.0), 0.2)
            self._body_floor_sum = self._body_floor_sum + w * (np.asarray(ankles_c, float)
                                                               - ankle_height_m * np.asarray(up_c, float))
            self._body_floor_w += w
        up = -np.asarray(up_c, float)
        along = float(up @ self.gravity)   # cos of the body's angle from the gravity in use
        if float(up @ self._gravity_cfg) < math.cos(math.radians(BODY_MAX_FROM_CONFIG_DEG)) \
                or along < math.cos(math.radians(BODY_MAX_FROM_CURRENT_DEG)):
            return False   # not an upright body (lying straight, a fit gone wrong) for any plausible mount
        if self._gravity_from == "body" and along < math.cos(math.radians(self.cfg.upright_trunk_deg)):
            return False   # tipping over: the first half second of a fall is a straight body too
        w = min(max(dt, 0.0), 0.2)   # a gap in the stream is no extra evidence
        if self._body_s >= BODY_MAX_S:
            self._body_sum *= 1.0 - w / BODY_MAX_S
        self._body_sum = self._body_sum - w * np.asarray(up_c, float)
        self._body_s = min(self._body_s + w, BODY_MAX_S)
        if self._gravity_imu is not None:
            return False
        return self._refresh()

    def observe_seated_trunk(self, up_c: np.ndarray | None, dt: float, ankles_c: np.ndarray | None = None,
                             ankle_height_m: float = 0.0) -> bool:
        """A seated person's trunk axis (unit, camera axes) for ``dt`` seconds: weaker evidence of gravity
        (people lean back or forward in a chair), counted ``SEATED_WEIGHT`` as much as a standing body and only
        until a standing body was seen. Their feet are on the floor as a standing person's are: ``ankles_c``
        and ``ankle_height_m`` give a floor point as :meth:`observe_body_axis` takes one. True when the gravity
        in use changed."""
        if self._body_s >= BODY_MIN_S or up_c is None:
            return False
        return self.observe_body_axis(up_c, SEATED_WEIGHT * dt, ankles_c, ankle_height_m)

    def _body_gravity(self) -> np.ndarray | None:
        """The standing body's gravity once ``BODY_MIN_S`` were seen and it contradicts the configured guess
        by more than ``BODY_REJECT_DEG`` (None: keep the guess)."""
        if self.tilt_measured or self._body_s < BODY_MIN_S - 1e-9:
            return None
        g = self._body_sum / np.linalg.norm(self._body_sum)
        if self._gravity_from != "body" and float(g @ self._gravity_cfg) > math.cos(math.radians(BODY_REJECT_DEG)) \
                and not self._feet_above_guess():
            return None
        return g

    def _feet_above_guess(self) -> bool:
        """Whether the guessed gravity puts the floor under the straight and seated bodies seen (BODY_MIN_S of
        them) at or above the camera: no camera above the floor sees the feet of a person on that floor there."""
        if self._body_floor_w < BODY_MIN_S - 1e-9:
            return False
        return float(self._body_floor_sum @ self._gravity_cfg) <= 0.0

    def _refresh(self) -> bool:
        cfg = self.cfg
        step = GRAVITY_STEP_DEG
        if self._robot is not None:
            g, src = self._robot[0], "robot"
        elif self._gravity_imu is not None:
            g, src = self._gravity_imu, "imu"
        elif self._depth is not None:
            g, src = self._depth[0], "depth"
        else:
            tilt, roll = self._learner.learned() if self._learner is not None else (None, None)
            tilt = tilt if cfg.camera_tilt_auto else None
            roll = roll if cfg.camera_roll_auto else None
            body = self._body_gravity()
            if body is not None and tilt is None:
                # the configured mount is a guess and nothing better is known: the standing body's own axis
                # (a learned roll replaces its roll)
                b_tilt, b_roll = tilt_roll_deg(body)
                g, src = gravity_from_tilt(b_tilt, roll if roll is not None else b_roll), "body"
                step = BODY_STEP_DEG
            else:
                g = gravity_from_tilt(tilt if tilt is not None else cfg.camera_tilt_deg,
                                      roll if roll is not None else cfg.camera_roll_deg)
                src = "learned" if tilt is not None else "config"
        previous = self._gravity_from
        self._gravity_from = src
        if float(g @ self.gravity) >= math.cos(math.radians(step)):
            return False  # the learned estimate drifts by less than a step: keep the gravity in use
        if src == "body" and previous in ("config", "body") and self._body_floor_w >= BODY_MIN_S - 1e-9 \
                and (self._floor_point is None or self._floor_weight < FLOOR_MIN_WEIGHT):
            # the guess rejected before a floor was learned (fewer than FLOOR_MIN_WEIGHT observations are none
            # yet): the floor under the straight and seated bodies seen
            self._floor_point = self._body_floor_sum / self._body_floor_w
            self._floor_weight = FLOOR_MIN_WEIGHT
        if src == "body" and previous in ("config", "body") and self._floor_point is not None \
                and float(self._floor_point @ g) > 0.0:
            # the guess rejected or the body's gravity refined: the floor seen under the feet is still a point on
            # the floor, re-projected along the new gravity (unless it comes out at or above the camera, which no
            # floor is: observe_floor); the standing height (metres) is kept through a refinement, but one
            # measured along a rejected guess, above its floor, is no measurement
            self._floor_learned = float(self._floor_point @ g)
            if previous == "config":
                self._stand, self._stand_weight = None, 0.0
                self._scale, self._scale_weight = None, 0.0
        else:
            self._floor_learned, self._floor_weight, self._floor_point = None, 0.0, None
            self._stand, self._stand_weight = None, 0.0
            self._scale, self._scale_weight = None, 0.0
        self._use(g)
        return True

    def _use(self, g: np.ndarray) -> None:
        self.gravity = g
        self.roll_deg = tilt_roll_deg(g)[1]

    # ------------------------------------------------------------------ floor and standing height

    @property
    def floor_below_camera(self) -> float | None:
        """The floor's distance below the camera along gravity (m): the robot's, measured in the depth image,
        learned or configured; None unknown. In the fit's metres: a measured height in true metres (the robot's,
        a configured one marked measured) is multiplied by the fit's scale once it is known (:meth:`fit_scale`)."""
        if self._robot is not None and self._robot[1] is not None:
            return self._in_fit_metres(self._robot[1])
        depth = self._depth_height()
        if depth is not None:
            return depth
        if self._floor_learned is not None and self._floor_weight >= FLOOR_MIN_WEIGHT:
            return self._floor_learned
        if self._gravity_from == "body" and not self.measured:
            return None   # the body contradicted the configured guess: its height is no better (lowest joint)
        # (a height configured on its own, with the tilt left at 0, is a measurement: kept along the body's gravity)
        return self._in_fit_metres(self._floor_cfg) if self.measured else self._floor_cfg

    def _true_metres_floor(self) -> float | None:
        """The floor height in true metres that the fit's scale is learned against: the robot's height, else the
        configured height of a mount marked measured; None with a depth floor (the fit has the depth image
        then: its metres are true ones) or without a measured height."""
        if self._depth is not None:
            return None
        if self._robot is not None:
            return self._robot[1]
        return self._floor_cfg if self.measured else None

    def fit_scale(self) -> float | None:
        """The fit's metres per true metre (after ``FLOOR_MIN_WEIGHT`` observations; None before, and with a
        depth floor): without depth the fit's lengths follow the body height it assumes
        (``fitting.body_height_m``), and so does every distance it places a body at, so the floor it sees under
        a standing person's feet is this share of the true one."""
        if self._depth is not None or self._scale is None or self._scale_weight < FLOOR_MIN_WEIGHT:
            return None
        return self._scale

    def _in_fit_metres(self, height_m: float | None) -> float | None:
        s = self.fit_scale()
        return height_m if height_m is None or s is None else s * height_m

    @property
    def floor_scaled(self) -> bool:
        """Whether :attr:`floor_below_camera` is a true-metre height put in the fit's metres (:meth:`fit_scale`)."""
        src = self.floor_source
        return (src == "robot" or (src == "config" and self.measured)) and self.fit_scale() is not None

    def metric_floor(self) -> float | None:
        """The floor's distance below the camera (m) when it was *measured*: the depth floor, else the configured
        height of a mount marked measured; None otherwise (a floor learned from a person's feet is in the fit's
        metres, which follow the body size the fit assumes)."""
        if self._robot is not None and self._robot[1] is not None:
            return self._robot[1]
        depth = self._depth_height()
        if depth is not None:
            return depth
        return self._floor_cfg if self.measured else None

    def _depth_height(self) -> float | None:
        """The depth floor's distance from the camera along the gravity in use (the IMU's may differ from the
        plane's normal by a degree or two); None without one, or when the two are further apart than 30 deg."""
        if self._depth is None:
            return None
        n, h, _ = self._depth
        c = float(n @ self.gravity)
        return h / c if c > math.cos(math.radians(30.0)) else None

    def observe_floor(self, below_camera_m: float, ankles_c: np.ndarray | None = None,
                      ankle_height_m: float = 0.0, standing: bool = False) -> None:
        """The floor seen below the feet of a person standing or sitting upright (m below the camera); ``ankles_c``
        (their ankles' point, camera axes) and ``ankle_height_m`` (the ankles' height above the floor) keep it as a
        point on the floor, so that a refined body gravity re-projects it instead of forgetting it. Feet at or
        above the camera's height are no floor (the gravity in use is wrong, as a guess 20 deg or more off puts
        feet a few metres away): dropped. ``standing``: a person standing upright on straight legs, whose ankles
        are an ankle's height above the floor by anatomy; with a height in true metres for this mount (the
        robot's, a configured one marked measured; no depth floor) the two give the fit's scale
        (:meth:`fit_scale`). Seated feet (on a footrest, tucked under a sofa) and a walker's lower ankle (the
        swing foot lifts) teach the floor, not the scale."""
        if self.cfg.learn_floor and below_camera_m > 0.0:   # feet above the camera: the gravity in use is wrong
            self._floor_learned, self._floor_weight = _ema(self._floor_learned, self._floor_weight, below_camera_m)
            true_m = self._true_metres_floor()
            if standing and true_m is not None:
                self._scale, self._scale_weight = _ema(self._scale, self._scale_weight, below_camera_m / true_m)
            if ankles_c is not None and np.all(np.isfinite(ankles_c)):
                w = min(self._floor_weight, EMA_MAX_WEIGHT)
                p = np.asarray(ankles_c, float) + ankle_height_m * self.gravity   # on the floor
                self._floor_point = p if self._floor_point is None or w <= 1.0 else \
                    self._floor_point + (p - self._floor_point) / w

    def forget_floor(self) -> None:
        """The learned floor is not under the person any more (another level): learn it again from their feet, and
        the fit's scale, learned from the same feet."""
        self._floor_learned, self._floor_weight, self._floor_point = None, 0.0, None
        self._scale, self._scale_weight = None, 0.0

    def observe_standing_pelvis(self, height_m: float) -> None:
        """The pelvis height above the floor of a person standing upright (m)."""
        self._stand, self._stand_weight = _ema(self._stand, self._stand_weight, height_m)

    def shift_standing_pelvis(self, delta_m: float) -> None:
        """The floor the standing pelvis height was measured against moved ``delta_m`` further below: so is the
        pelvis above it."""
        if self._stand is not None:
            self._stand += delta_m

    def standing_pelvis(self) -> float | None:
        """The learned standing pelvis height (m), or None until it is known."""
        return self._stand if self._stand is not None and self._stand_weight >= STAND_MIN_WEIGHT else None

    # ------------------------------------------------------------------ kept across restarts

    def state(self) -> dict:
        """What was learned from people (gravity from their bodies or image lines, the floor under their feet,
        their standing height) with how much evidence stands behind each, as JSON-able numbers; the IMU and the
        robot are live and not kept (while the robot gives the pose: what was learned before it). ``config``
        records the configured values it was learned under."""
        if self._before_robot is not None:
            return self._before_robot
        cfg = self.cfg
        return {
            "version": STATE_VERSION,
            "config": {k: getattr(cfg, k) for k in STATE_CONFIG_KEYS},
            "gravity": self.gravity.tolist(), "gravity_from": self._gravity_from,
            "body": {"sum": self._body_sum.tolist(), "seconds": self._body_s,
                     "floor_sum": self._body_floor_sum.tolist(), "floor_seconds": self._body_floor_w},
            "learner": self._learner.state() if self._learner is not None else None,
            "floor": None if self._floor_learned is None else {
                "below_camera_m": self._floor_learned, "weight": self._floor_weight,
                "point": None if self._floor_point is None else self._floor_point.tolist()},
            "standing_pelvis": None if self._stand is None else {"m": self._stand, "weight": self._stand_weight},
        }

    def restore(self, state: dict) -> str | None:
        """Take back :meth:`state` from an earlier run of the same camera. Returns None when restored, else why
        not (another version, learned under other configured values); raises ValueError (KeyError, TypeError)
        when it is malformed. The IMU, when there is one, still replaces the gravity."""
        if state.get("version") != STATE_VERSION:
            return f"version {state.get('version')!r} is not {STATE_VERSION}"
        stored = state.get("config") or {}
        changed = [k for k in STATE_CONFIG_KEYS if stored.get(k) != getattr(self.cfg, k)]
        if changed:
            return "learned under other configured values (" + ", ".join(changed) + ")"
        g = _vector(state["gravity"])
        body = state["body"]
        self._body_sum, self._body_s = _vector(body["sum"], unit=False), float(body["seconds"])
        self._body_floor_sum, self._body_floor_w = _vector(body["floor_sum"], unit=False), float(body["floor_seconds"])
        if self._learner is not None and state.get("learner") is not None:
            self._learner.restore(state["learner"])
        self._gravity_from = "config"
        self._refresh()                      # the gravity these give (forgets floor and standing height)
        if float(g @ self.gravity) >= math.cos(math.radians(GRAVITY_STEP_DEG)):
            floor, stand = state.get("floor"), state.get("standing_pelvis")
            if floor is not None:            # learned along this same gravity: still valid
                self._floor_learned, self._floor_weight = float(floor["below_camera_m"]), float(floor["weight"])
                self._floor_point = None if floor.get("point") is None else _vector(floor["point"], unit=False)
            if stand is not None:
                self._stand, self._stand_weight = float(stand["m"]), float(stand["weight"])
        self.restored = True
        return None

    # ------------------------------------------------------------------ report

    @property
    def floor_source(self) -> str:
        """Where :attr:`floor_below_camera` comes from: robot, depth, learned (from feet), config or lowest_joint
        (unknown: the lowest fitted joint stands in)."""
        if self._robot is not None and self._robot[1] is not None:
            return "robot"
        if self._depth_height() is not None:
            return "depth"
        if self._floor_learned is not None and self._floor_weight >= FLOOR_MIN_WEIGHT:
            return "learned"
        return "config" if self.floor_below_camera is not None else "lowest_joint"

    def used(self) -> dict:
        """What a frame is judged with: ``gravity`` robot, imu, depth (the floor plane in the depth image),
        learned, body (the standing person's axis) or config; ``floor`` robot, depth, learned (from feet), config
        or lowest_joint (unknown: the lowest fitted joint stands in); ``config`` whether the configured values
        were measured (``camera_geometry``); ``depth_floor`` the depth floor's evidence when there is one,
        ``robot_mount`` the robot's."""
        gravity = "robot" if self._robot is not None else "imu" if self._gravity_imu is not None else self._gravity_from
        out = {"gravity": gravity, "floor": self.floor_source, "config": "measured" if self.measured else "guess"}
        if self._depth is not None:
            out["depth_floor"] = self._depth_evidence()
        if self._robot is not None:
            out["robot_mount"] = self._robot_evidence()
        return out

    def _robot_evidence(self) -> dict:
        _, h, evidence = self._robot
        return {**({} if h is None else {"height_m": round(h, 4)}), **evidence}

    def _depth_evidence(self) -> dict:
        n, h, evidence = self._depth
        return {"height_m": round(h, 4), **{k: v for k, v in evidence.items() if k != "height_m"}}

    def summary(self) -> dict:
        """Tilt and roll (deg), floor below the camera (m, None unknown; a measured height as given, in true
        metres, though it is judged in the fit's: :meth:`fit_scale`), where each comes from (config,
        learned, robot, imu, depth, body; height: robot, depth, learned, config, unknown), the depth floor's
        evidence (``depth_floor``: height, tilt, roll, inliers, residual, age, ... when there is one), the robot's
        (``robot_mount``: height, age, source, ... while it gives the pose), whether the configured values are
        trusted (``config``: measured or guess) and the seconds of standing the learner has seen."""
        tilt, roll = tilt_roll_deg(self.gravity)
        l_tilt, l_roll = self._learner.learned() if self._learner is not None else (None, None)
        src = "robot" if self._robot is not None else "imu" if self._gravity_imu is not None \
            else "depth" if self._depth is not None else None
        body = self._gravity_from == "body"
        extra = {} if self._depth is None else {"depth_floor": self._depth_evidence()}
        if self._robot is not None:
            extra["robot_mount"] = self._robot_evidence()
        floor = self.floor_below_camera
        if floor is not None and self.floor_scaled:   # shown as given (true metres), judged in the fit's
            floor /= self.fit_scale()
        return {"tilt_deg": tilt, "roll_deg": roll, "floor_below_camera_m": floor,
                "tilt_from": src or ("learned" if l_tilt is not None and self.cfg.camera_tilt_auto
                                     else "body" if body else "config"),
                "roll_from": src or ("learned" if l_roll is not None and self.cfg.camera_roll_auto
                                     else "body" if body else "config"),
                "height_from": "unknown" if self.floor_source == "lowest_joint" else self.floor_source,
                "config": "measured" if self.measured else "guess",
                "body_s": round(self._body_s, 2), "floor_weight": round(self._floor_weight, 1),
                "restored": self.restored,
                "standing_s": 0.0 if self._learner is None else round(self._learner.seconds, 2), **extra}


def _vector(value, unit: bool = True) -> np.ndarray:
    v = np.asarray(value, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or (unit and not 0.5 < float(np.linalg.norm(v)) < 1.5):
        raise ValueError(f"expected three finite numbers{' (a unit vector)' if unit else ''}, got {value!r}")
    return v / np.linalg.norm(v) if unit else v


def _ema(value: float | None, weight: float, obs: float, max_weight: float = EMA_MAX_WEIGHT) -> tuple[float, float]:
    """Running mean that becomes an exponential average after ``max_weight`` observations."""
    if value is None or not math.isfinite(value):
        return obs, 1.0
    weight = min(weight + 1.0, max_weight)
    return value + (obs - value) / weight, weight
