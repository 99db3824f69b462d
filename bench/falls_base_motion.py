"""The moving-camera fall benchmark's heads that pan, and a robot base that drives (``--camera follow_pan|drive``).

:mod:`bench.falls_moving` holds the protocol and the heads that only tilt (``static``, ``follow``, ``nod``); this
module holds the two motions of a robot that follows the person around the room:

* ``follow_pan`` (:class:`PanTiltHead`): the head pans *and* tilts to keep the mid-hip on the image's centre,
  with the delay, servo time constant and tilt rate limit of ``follow`` and a pan rate limit from the same pan-tilt
  cameras' speed tables. The base stays where the scene's camera is.
* ``drive`` (:class:`DriveBase`): the base drives on the floor (the camera's height stays the scene's) to keep a
  set distance from the person, turning to face them, speed and acceleration limited; the head follows on it as
  in ``follow_pan``. The base's acceleration and yaw rate reach the ``imu`` and ``imu_gyro`` arms as an IMU on
  the head would feel them (:func:`accel_sample`, :func:`camera_rate`).

Both run one controller (:class:`PanTiltController`), stepped at 200 Hz between the frames' capture times, that
records every step (:class:`Track`) so the IMU arms can sample the motion at their own rates.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, replace

import numpy as np

from posed.bench.falls_body import WorldCamera

HIPS = (23, 24)
G_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class PanTiltHead:
    """A pan-tilt head following the person's mid-hip with both axes.

    * ``delay_s``, ``tau_s``, ``max_tilt_rate_deg_s``, the tilt range and ``step_s``: those of
      :class:`bench.falls_moving.FollowHead` (the ``follow`` head), so the two heads differ by the pan alone.
    * ``max_pan_rate_deg_s`` 80: the pan of the same pan-tilt cameras tops out at 80 deg/s (Sony EVI-D30, its
      fastest speed code, 18h) to 300 deg/s (EVI-D100), by the EVI-D100 technical manual's pan/tilt speed table
      (page 44, both cameras side by side; their tilt: 50 and 125 deg/s, which gave ``follow`` its 60). The
      slower camera's maximum, as ``follow``'s 60 deg/s sits near the slower tilt: at 80 deg/s a 10 ms exposure
      smears 0.8 deg, 7.4 px of a 640 px, 69 deg image.
    * ``max_pan_deg`` 100: the EVI-D30's and EVI-D100's pan range, +-100 deg (the same manual, page 45).
    """

    delay_s: float = 0.15
    tau_s: float = 0.15
    max_tilt_rate_deg_s: float = 60.0
    max_pan_rate_deg_s: float = 80.0
    max_pan_deg: float = 100.0
    step_s: float = 0.005
    min_tilt_deg: float = -30.0
    max_tilt_deg: float = 60.0

    def meaning(self) -> str:
        return (f"the head pans and tilts to keep the pelvis on the image's centre: it sees each frame's landmarks "
                f"{self.delay_s:g} s after capture, its servos follow with a {self.tau_s:g} s time constant, at most "
                f"{self.max_pan_rate_deg_s:g} deg/s in pan (+-{self.max_pan_deg:g} deg) and "
                f"{self.max_tilt_rate_deg_s:g} deg/s in tilt; the base stays at the scene's camera")


@dataclass(frozen=True)
class DriveBase:
    """A robot base that keeps ``distance_m`` from the person, turning to face them.

    Why these numbers:

    * ``max_speed_m_s`` 0.5: a ROS navigation (DWA planner) configuration for the Kobuki base (TurtleBot 2, a
      common home and research robot) sets ``max_trans_vel: 0.5``, "slightly less than the base's capability";
      a vision-based person follower for elderly care kept pace with its user at 0.47-0.54 m/s
      (Kurumbaparambil et al., "Vision-Based Person-Following Algorithm for Assistive Elderly-Care Quadruped
      Robots", MDPI Sensors, doi 10.3390/s26103263). Sources: docs/bench/falls.md, "A head that pans and a base
      that drives".
    * ``max_accel_m_s2`` 0.5, ``max_decel_m_s2`` 0.6, ``max_yaw_accel_deg_s2`` 200.5 (3.5 rad/s^2): the Kobuki
      driver's own acceleration limiter's defaults (kobuki_driver ``AccelerationLimiter::init``: linear
      0.5 m/s^2, deceleration 0.5 * 1.2, angular 3.5 rad/s^2).
    * ``max_yaw_rate_deg_s`` 90: chosen, not cited (below the 5 rad/s of the same DWA configuration); the head's
      pan covers what the base has not turned yet.
    * ``distance_m`` 2.0 and the gains (``speed_gain_per_s`` 1: 1 m/s per m of error before the limits;
      ``yaw_tau_s`` 0.5): chosen. The base sees the person's mid-hip as a depth camera gives it (the true world
      position of the frame's hips, no depth noise) when both hips are in the image, ``delay_s`` of the head
      after capture; it drives only along its heading (a differential drive), scaled by the cosine of the
      bearing to the person, and reverses when the person comes closer than ``distance_m``.
    * It starts at rest ``distance_m`` from the first frame's mid-hip, on the line from there to the scene's
      camera, facing the person, at the camera's height, the head at the scene's home tilt. The camera sits on
      the base's vertical turning axis (so the base's yaw gives it no centripetal acceleration).
    """

    distance_m: float = 2.0
    max_speed_m_s: float = 0.5
    max_accel_m_s2: float = 0.5
    max_decel_m_s2: float = 0.6
    max_yaw_rate_deg_s: float = 90.0
    max_yaw_accel_deg_s2: float = math.degrees(3.5)
    speed_gain_per_s: float = 1.0
    yaw_tau_s: float = 0.5

    def meaning(self) -> str:
        return (f"the base drives on the floor to keep {self.distance_m:g} m from the person's pelvis, facing them "
                f"(at most {self.max_speed_m_s:g} m/s, {self.max_accel_m_s2:g} m/s^2 speeding up, "
                f"{self.max_decel_m_s2:g} m/s^2 slowing down, {self.max_yaw_rate_deg_s:g} deg/s and "
                f"{math.radians(self.max_yaw_accel_deg_s2):g} rad/s^2 turning), the camera's height constant; the "
                "head pans and tilts on it as in follow_pan; the IMU feels the base's acceleration and yaw")


PAN = PanTiltHead()
DRIVE = DriveBase()
BASE_MOTIONS = ("follow_pan", "drive")


def wrap180(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def azimuth(dx: float, dy: float) -> float:
    """The yaw (deg, :class:`WorldCamera`'s: from +y, counter-clockwise) of the horizontal direction (dx, dy)."""
    return math.degrees(math.atan2(-dx, dy))


def mid_hip(world: dict) -> np.ndarray:
    return 0.5 * (np.asarray(world["left_hip"], float) + np.asarray(world["right_hip"], float))


def seen_hips(landmarks: np.ndarray | None) -> np.ndarray | None:
    """The two hips' landmark rows (u, v, z, visibility) when both are seen (visibility 0.5 or more), else None:
    what a head that follows the person aims at."""
    if landmarks is None:
        return None
    hips = landmarks[list(HIPS)]
    return None if np.any(hips[:, 3] < 0.5) else hips


@dataclass
class Track:
    """Every controller step: time, base position and heading, the camera's yaw and tilt, the base's forward
    speed and its world acceleration (x, y) over the step that ends then."""

    t: list
    x: list
    y: list
    heading: list
    yaw: list
    tilt: list
    speed: list
    ax: list
    ay: list

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v, dtype=float) for k, v in self.__dict__.items()}


class PanTiltController:
    """The ``follow_pan`` head, on a base that drives (``base`` a :class:`DriveBase`) or stays (None).

    ``camera_at(t)`` runs the controller on to capture time ``t`` and returns the camera then; ``observe(t,
    landmarks, camera, world)`` gives it a frame's landmarks as seen through ``camera`` (and the frame's world
    joints, the base's depth reading of the hips). A frame without both hips in view leaves every target where
    it was."""

    def __init__(self, home: WorldCamera, head: PanTiltHead = PAN, base: DriveBase | None = None,
                 start_xy: tuple[float, float] | None = None, start_heading: float | None = None) -> None:
        self.home, self.head, self.base = home, head, base
        self.x, self.y = (home.x, home.y) if start_xy is None else (float(start_xy[0]), float(start_xy[1]))
        self.heading = float(home.yaw if start_heading is None else start_heading)
        self.pan = 0.0
        self.tilt = float(home.tilt)
        self.speed = 0.0                       # m/s along the heading
        self.yaw_rate = 0.0                    # deg/s
        self.gaze: tuple[float, float] | None = None      # target (world yaw, tilt) of the camera
        self.person: np.ndarray | None = None             # the person's mid-hip (world x, y), as depth gives it
        self.t = 0.0
        self.pending: list[tuple[float, tuple[float, float], np.ndarray | None]] = []
        self.max_pan_rate_seen = self.max_tilt_rate_seen = 0.0
        self.track = Track([0.0], [self.x], [self.y], [self.heading], [self.heading + self.pan], [self.tilt],
                           [0.0], [0.0], [0.0])

    def camera(self) -> WorldCamera:
        return replace(self.home, x=self.x, y=self.y, yaw=self.heading + self.pan, tilt=self.tilt)

    def gaze_from(self, landmarks: np.ndarray | None, camera: WorldCamera) -> tuple[float, float] | None:
        """The camera yaw and tilt (deg, world) whose optical axis passes through the frame's mid-hip pixel, or
        None (hips not both seen)."""
        hips = seen_hips(landmarks)
        if hips is None:
            return None
        u, v = float(hips[:, 0].mean()), float(hips[:, 1].mean())
        k = camera.intrinsics
        ray = np.array([(u - camera.width / 2.0) / k.fx, (v - camera.height / 2.0) / k.fy, 1.0])
        d = camera.axes.T @ ray                      # the ray in the room
        tilt = math.degrees(math.atan2(-d[2], math.hypot(d[0], d[1])))
        return azimuth(d[0], d[1]), float(np.clip(tilt, self.head.min_tilt_deg, self.head.max_tilt_deg))

    def observe(self, t: float, landmarks: np.ndarray | None, camera: WorldCamera, world: dict | None = None) -> None:
        gaze = self.gaze_from(landmarks, camera)
        if gaze is not None:
            person = mid_hip(world)[:2] if world is not None and self.base is not None else None
            self.pending.append((t + self.head.delay_s, gaze, person))

    def _step_base(self, dt: float) -> tuple[float, float]:
        """One step of the base towards its targets; its world acceleration (x, y) over the step."""
        b = self.base
        if b is None or self.person is None:
            return 0.0, 0.0
        dx, dy = self.person[0] - self.x, self.person[1] - self.y
        dist = math.hypot(dx, dy)
        bearing = wrap180(azimuth(dx, dy) - self.heading) if dist > 1e-6 else 0.0
        r_cmd = max(-b.max_yaw_rate_deg_s, min(b.max_yaw_rate_deg_s, bearing / b.yaw_tau_s))
        dr = max(-b.max_yaw_accel_deg_s2 * dt, min(b.max_yaw_accel_deg_s2 * dt, r_cmd - self.yaw_rate))
        v_cmd = b.speed_gain_per_s * (dist - b.distance_m) * max(math.cos(math.radians(bearing)), 0.0)
        v_cmd = max(-b.max_speed_m_s, min(b.max_speed_m_s, v_cmd))
        speeding_up = abs(v_cmd) > abs(self.speed) and v_cmd * self.speed >= 0.0
        lim = (b.max_accel_m_s2 if speeding_up else b.max_decel_m_s2) * dt
        v0, h0 = self.speed, self.heading
        self.speed += max(-lim, min(lim, v_cmd - self.speed))
        self.yaw_rate += dr
        self.heading += self.yaw_rate * dt
        # the position integrates the velocity exactly for the step's constant acceleration and yaw rate
        # (trapezoid of the two end velocities: second order, well below a millimetre at 5 ms)
        hx0, hy0 = -math.sin(math.radians(h0)), math.cos(math.radians(h0))
        hx1, hy1 = -math.sin(math.radians(self.heading)), math.cos(math.radians(self.heading))
        vx0, vy0, vx1, vy1 = v0 * hx0, v0 * hy0, self.speed * hx1, self.speed * hy1
        self.x += 0.5 * (vx0 + vx1) * dt
        self.y += 0.5 * (vy0 + vy1) * dt
        return (vx1 - vx0) / dt, (vy1 - vy0) / dt

    def run_to(self, t: float) -> None:
        if t <= self.t:
            return
        h = self.head
        n = max(1, int(math.ceil((t - self.t) / h.step_s - 1e-9)))
        dt = (t - self.t) / n
        for i in range(1, n + 1):
            now = self.t + i * dt
            while self.pending and self.pending[0][0] <= now + 1e-12:
                _, self.gaze, person = self.pending.pop(0)
                if person is not None:
                    self.person = person
            ax, ay = self._step_base(dt)
            if self.gaze is not None:
                pan_target = max(-h.max_pan_deg, min(h.max_pan_deg, wrap180(self.gaze[0] - self.heading)))
                pan_rate = max(-h.max_pan_rate_deg_s, min(h.max_pan_rate_deg_s, (pan_target - self.pan) / h.tau_s))
                tilt_rate = max(-h.max_tilt_rate_deg_s, min(h.max_tilt_rate_deg_s,
                                                            (self.gaze[1] - self.tilt) / h.tau_s))
                self.pan += pan_rate * dt
                self.tilt += tilt_rate * dt
                self.max_pan_rate_seen = max(self.max_pan_rate_seen, abs(pan_rate))
                self.max_tilt_rate_seen = max(self.max_tilt_rate_seen, abs(tilt_rate))
            tr = self.track
            for name, value in (("t", now), ("x", self.x), ("y", self.y), ("heading", self.heading),
                                ("yaw", self.heading + self.pan), ("tilt", self.tilt), ("speed", self.speed),
                                ("ax", ax), ("ay", ay)):
                getattr(tr, name).append(value)
        self.t = t

    def camera_at(self, t: float) -> WorldCamera:
        self.run_to(t)
        return self.camera()

    def tilt_at(self, t: float) -> float:
        return float(np.interp(t, self.track.t, self.track.tilt))

    def pose_at(self, t: float) -> tuple[float, float, np.ndarray]:
        """The camera's yaw and tilt (deg) at ``t`` (linear between steps) and the base's world acceleration
        (m/s^2, x, y, z) during the step that holds ``t``."""
        tr = self.track
        yaw = float(np.interp(t, tr.t, tr.yaw))
        tilt = float(np.interp(t, tr.t, tr.tilt))
        k = min(int(np.searchsorted(tr.t, t, side="left")), len(tr.t) - 1)
        return yaw, tilt, np.array([tr.ax[k], tr.ay[k], 0.0])


def head_for(motion: str, home: WorldCamera, first_world: dict | None, head: PanTiltHead = PAN,
             base: DriveBase = DRIVE) -> PanTiltController:
    if motion == "follow_pan":
        return PanTiltController(home, head)
    if motion == "drive":
        if first_world is None:
            return PanTiltController(home, head, base)
        p = mid_hip(first_world)
        away = np.array([home.x - p[0], home.y - p[1]])
        n = float(np.linalg.norm(away))
        if n > 1e-9:
            away = away / n
        else:                                          # the person under the camera: back off along its view
            away = np.array([math.sin(math.radians(home.yaw)), -math.cos(math.radians(home.yaw))])
        start = p[:2] + base.distance_m * away
        return PanTiltController(home, head, base, (float(start[0]), float(start[1])), azimuth(-away[0], -away[1]))
    raise ValueError(f"{motion!r} is not one of {', '.join(BASE_MOTIONS)}")


# ---------------------------------------------------------------------------- the head's IMU


def camera_axes(yaw: float, tilt: float, roll: float) -> np.ndarray:
    """Rows: the camera's x (right), y (down), z (forward) in the room, as :class:`WorldCamera` places them."""
    return WorldCamera(yaw=yaw, tilt=tilt, roll=roll).axes


def accel_sample(yaw: float, tilt: float, roll: float, accel_world: np.ndarray, g: float) -> np.ndarray:
    """What an accelerometer fixed to the camera reads (m/s^2, camera axes): the specific force, the base's
    acceleration minus gravity's, i.e. ``a + g up`` turned into the camera's axes (at rest: ``-g down``)."""
    return camera_axes(yaw, tilt, roll) @ (np.asarray(accel_world, float) + g * G_UP)


def camera_rate(yaw0: float, tilt0: float, yaw1: float, tilt1: float, roll: float, dt: float) -> np.ndarray:
    """The constant angular rate (rad/s, the camera's axes, right-handed) that turns the camera from (yaw0,
    tilt0) to (yaw1, tilt1) in ``dt`` seconds: with C the room-to-camera rotation, C1 = exp(-[w]x dt) C0, so
    w dt is minus the rotation vector of C1 C0^T."""
    c0, c1 = camera_axes(yaw0, tilt0, roll), camera_axes(yaw1, tilt1, roll)
    r = c1 @ c0.T
    cos_a = max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))
    angle = math.acos(cos_a)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-12:
        return -0.5 * v / dt
    return -(angle / (2.0 * math.sin(angle))) * v / dt


def base_imu_downs(mc, gyro: bool, rate_hz: float, gyro_hz: float, noise_density_deg_s: float, bias_deg_s: float,
                   bias: np.ndarray, noise_seed: int) -> list[tuple[float, float, float] | None]:
    """Each frame's gravity as the head's IMU gives it through :class:`hal.imu.GravityEstimate`, for a head
    that pans and a base that drives (``mc.pose_at``): the accelerometer reads the specific force
    (:func:`accel_sample`: gravity and the base's acceleration, no noise) at ``rate_hz``; with ``gyro``, the gyro
    at ``gyro_hz`` reads the camera's mean angular rate since its previous sample (:func:`camera_rate`: base yaw,
    pan and tilt together) plus white noise and the scene's constant ``bias`` (rad/s, drawn within
    ``bias_deg_s`` as the tilting heads' is)."""
    from posed.hal import G_M_S2, GravityEstimate

    est = GravityEstimate()
    roll = mc.case.camera.roll
    rng = np.random.default_rng(noise_seed)
    sigma = math.radians(noise_density_deg_s) * math.sqrt(gyro_hz / 2.0)
    out = []
    k = j = 0
    prev = None
    for fr in mc.case.frames:
        while k / rate_hz <= fr.t + 1e-12:
            ts = k / rate_hz
            yaw, tilt, acc = mc.pose_at(ts)
            est.add(ts, *accel_sample(yaw, tilt, roll, acc, G_M_S2))
            k += 1
        while gyro and j / gyro_hz <= fr.t + 1e-12:
            ts = j / gyro_hz
            yaw, tilt, _ = mc.pose_at(ts)
            w = camera_rate(prev[0], prev[1], yaw, tilt, roll, 1.0 / gyro_hz) if prev is not None else np.zeros(3)
            est.add_gyro(ts, *(w + bias + rng.normal(0.0, sigma, 3)))
            prev = (yaw, tilt)
            j += 1
        out.append(est.at(fr.t))
    return out


def base_summary(cases) -> dict:
    """How far the camera travelled and turned, and the base's fastest speed and acceleration, over the cases
    of one motion."""
    travel, turn, speed, accel = [], [], [], []
    for mc in cases:
        tr = mc.track.arrays()
        travel.append(float(np.sum(np.hypot(np.diff(tr["x"]), np.diff(tr["y"])))))
        turn.append(float(np.max(np.abs([wrap180(a - mc.case.camera.yaw) for a in tr["yaw"]]))))
        speed.append(float(np.max(np.abs(tr["speed"]))))
        accel.append(float(np.max(np.hypot(tr["ax"], tr["ay"]))))

    def med_max(v):
        return {"median": round(statistics.median(v), 2), "max": round(max(v), 2)} if v else None

    return {"travel_m": med_max(travel), "yaw_from_home_deg": med_max(turn), "speed_max_m_s": med_max(speed),
            "accel_max_m_s2": med_max(accel)}


__all__ = ["BASE_MOTIONS", "DRIVE", "PAN", "DriveBase", "PanTiltController", "PanTiltHead", "Track", "accel_sample",
           "azimuth", "base_imu_downs", "base_summary", "camera_axes", "camera_rate", "head_for", "mid_hip"]
