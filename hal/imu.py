"""The direction of gravity from a camera's accelerometer and, when it has one, its gyroscope (RealSense D435i,
D455), in the colour camera's axes.

Axes: the colour camera's (x image right, y image down, z forward, as :mod:`camera_model`). librealsense
reports every accelerometer sample already turned into the depth sensor's axes (x right, y down, z forward),
in m/s^2; the depth -> colour rotation (extrinsics, a fraction of a degree on a D435i) turns it into the colour
camera's. An accelerometer measures the support's push, not gravity: a camera at rest, level, reads about
(0, -9.8, 0). The **down** direction is therefore the opposite of the reading.

Filtering: a robot's camera tilts slowly (the robot turns, drives over a threshold, a head joint moves) but
shakes and accelerates fast. Each sample whose magnitude is within ``tolerance`` (a fraction of g) of g counts;
the rest are the robot accelerating or a bump, and are skipped (counted). Accepted samples are averaged by an
exponential moving average with time constant ``time_constant_s`` (in sample time, so the rate does not
matter), and the average normalized. Until ``min_samples`` samples have been accepted there is no estimate.

Gyroscope (a D435i's or D455's BMI055, 200 or 400 Hz): when its samples come (``add_gyro``), the filter
becomes a complementary one. librealsense gives the angular rate in rad/s in the same depth-sensor axes as the
accelerometer (right-handed), turned into the colour camera's by the same rotation. A direction fixed in the
room, seen from a camera turning at rate w (camera axes), changes as dv/dt = -w x v; so before each gyro
sample's time the averaged down is turned by the angle |w| dt about -w (dt: the time since the previous gyro
sample, the rate taken as constant over it; a gap over ``GYRO_MAX_GAP_S`` is not integrated). The exponential
average then works on the turned average: every accelerometer sample still pulls it with weight
1 - exp(-dt / time_constant_s), but what was averaged before is turned with the camera rather than left
behind, so a head that tilts is followed at once, and the accelerometer only corrects what the gyro gets wrong.
Without gyro samples nothing changes: the same code, the same numbers as the accelerometer-only filter.

The time constant with the gyro (the same ``TIME_CONSTANT_S``, 0.5 s), from the BMI055's datasheet
(Bosch BST-BMI055-DS000; typical values): a gyro bias b the filter does not know turns the estimate on
until the accelerometer's pull balances it, a steady error of b * tau (first order: e' = b - e / tau); the
zero-rate offset is +-1 deg/s (+-3 max; 0.015 deg/s/K over temperature; the D435i's IMU is not calibrated at
the factory), so 0.5 deg at tau = 0.5 s. The other noise terms are negligible at any tau of this order: the
gyro's noise density 0.014 deg/s/sqrt(Hz) gives an angle random walk whose share in the estimate is
0.014 * sqrt(tau / 2) = 0.007 deg, the accelerometer's 150 ug/sqrt(Hz) gives 150e-6 / sqrt(4 tau) rad
= 0.006 deg. What bounds tau from below is not noise but the camera's own accelerations, which the
accelerometer cannot tell from a tilt: a head joint that starts or stops turning at w changes the velocity of
an IMU r = 5 cm off its axis by r * w (60 deg/s: 0.05 m/s), which tilts the average by r * w / (g * tau); the
two errors are equal at tau = sqrt(r w / (g b)) = 0.55 s (b = 1 deg/s). So the accelerometer-only filter's
0.5 s stays: it rejects the robot's accelerations as much as before, and the gyro's bias costs at most
about 0.5 deg. No bias is estimated: a static camera with a bias b settles within b * tau of the truth
(``tests/hal/test_imu_gyro.py`` checks that bound), and an estimate of it would learn the robot's accelerations too.

Time: samples carry the device's timestamp (seconds, the same clock as the camera's frames). ``at(t)`` uses
only the samples stamped at or before ``t`` (accelerometer and gyro, in time order; a gyro sample first when
both have the same stamp, since it turns the camera up to that time) and keeps the later ones for the next
frame, so a recording gives every frame the same gravity however fast it is played. Samples are added from
librealsense's threads and read by the frame reader: every method takes a lock.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

G_M_S2 = 9.80665            # standard gravity
TIME_CONSTANT_S = 0.5       # the low-pass: a tilt change is followed within ~3 time constants (1.5 s) without a
                            # gyro; with one, the accelerometer's pull on the gyro's drift (module doc: why 0.5 s)
TOLERANCE = 0.2             # a sample counts when | |a| - g | <= 0.2 g (a robot braking at 2 m/s^2 does not)
MIN_SAMPLES = 10            # accepted samples before the first estimate (0.16 s at the D435i's 63 Hz)
MAX_PENDING = 4096          # samples waiting for a frame: older ones are folded in without waiting
GYRO_MAX_GAP_S = 0.1        # a longer gap between gyro samples (lost samples) is not integrated (20 at 200 Hz)


class GravityEstimate:
    """Accelerometer (and gyro) samples -> the unit down vector in the colour camera's axes (module doc).

    ``rotation``: 3 x 3, turns a sample from the accelerometer's (and gyro's) axes into the colour camera's
    (identity when the two agree)."""

    def __init__(self, rotation: np.ndarray | None = None, time_constant_s: float = TIME_CONSTANT_S,
                 tolerance: float = TOLERANCE, min_samples: int = MIN_SAMPLES) -> None:
        r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise ValueError(f"rotation must be a finite 3 x 3 matrix, got {r!r}")
        if not time_constant_s > 0 or not 0 < tolerance < 1 or min_samples < 1:
            raise ValueError(f"time_constant_s > 0, 0 < tolerance < 1 and min_samples >= 1 needed, got "
                             f"{time_constant_s}, {tolerance}, {min_samples}")
        self.rotation = r
        self.time_constant_s = float(time_constant_s)
        self.tolerance = float(tolerance)
        self.min_samples = int(min_samples)
        self._lock = threading.Lock()
        self._pending: deque[tuple[float, float, float, float]] = deque()
        self._gyro_pending: deque[tuple[float, float, float, float]] = deque()
        self._mean: np.ndarray | None = None   # low-passed down vector (m/s^2), colour axes
        self._t_last: float | None = None
        self.accepted = 0
        self.rejected = 0                      # accelerating, a bump, or not a finite reading
        self._tg_last: float | None = None     # the last gyro sample's time
        self.gyro_samples = 0
        self.gyro_rejected = 0                 # not a finite reading

    def add(self, t_s: float, ax: float, ay: float, az: float) -> None:
        """One accelerometer sample: device time (s) and specific force (m/s^2, the accelerometer's axes)."""
        with self._lock:
            self._pending.append((float(t_s), float(ax), float(ay), float(az)))
            while len(self._pending) > MAX_PENDING:
                self._fold_next()

    def add_gyro(self, t_s: float, wx: float, wy: float, wz: float) -> None:
        """One gyroscope sample: device time (s) and angular rate (rad/s, right-handed, the accelerometer's
        axes)."""
        with self._lock:
            self._gyro_pending.append((float(t_s), float(wx), float(wy), float(wz)))
            while len(self._gyro_pending) > MAX_PENDING:
                self._fold_next()

    def at(self, t_s: float) -> tuple[float, float, float] | None:
        """The down direction (unit vector, colour camera axes) from the samples stamped at or before ``t_s``,
        or None while fewer than ``min_samples`` samples have been accepted."""
        with self._lock:
            while True:
                nxt = self._next_time()
                if nxt is None or not nxt <= t_s:
                    break
                self._fold_next()
            if self._mean is None or self.accepted < self.min_samples:
                return None
            n = float(np.linalg.norm(self._mean))
            if not n > 0:
                return None
            g = self._mean / n
            return (float(g[0]), float(g[1]), float(g[2]))

    def counters(self) -> dict[str, int]:
        """Accepted and rejected accelerometer samples; gyro samples too once there were any."""
        with self._lock:
            out = {"imu_samples": self.accepted, "imu_rejected": self.rejected}
            if self.gyro_samples or self.gyro_rejected:
                out.update(imu_gyro_samples=self.gyro_samples, imu_gyro_rejected=self.gyro_rejected)
            return out

    def _next_time(self) -> float | None:
        """The stamp of the next sample to fold (a gyro sample first on a tie), or None."""
        ta = self._pending[0][0] if self._pending else None
        tg = self._gyro_pending[0][0] if self._gyro_pending else None
        if ta is None or (tg is not None and not tg > ta):
            return tg
        return ta

    def _fold_next(self) -> None:
        """Fold the earlier of the two queues' first samples (the gyro's on a tie)."""
        if self._gyro_pending and (not self._pending or not self._gyro_pending[0][0] > self._pending[0][0]):
            self._fold_gyro(self._gyro_pending.popleft())
        elif self._pending:
            self._fold(self._pending.popleft())

    def _fold_gyro(self, sample: tuple[float, float, float, float]) -> None:
        t, wx, wy, wz = sample
        w = self.rotation @ np.array((wx, wy, wz))
        if not (math.isfinite(t) and bool(np.all(np.isfinite(w)))):
            self.gyro_rejected += 1
            return
        prev = self._tg_last
        self._tg_last = t if prev is None else max(prev, t)
        self.gyro_samples += 1
        if prev is None or self._mean is None:
            return
        dt = t - prev
        if 0.0 < dt <= GYRO_MAX_GAP_S:
            self._mean = propagate(self._mean, w, dt)

    def _fold(self, sample: tuple[float, float, float, float]) -> None:
        t, ax, ay, az = sample
        a = np.array((ax, ay, az))
        norm = float(np.linalg.norm(a))
        if not (math.isfinite(t) and math.isfinite(norm)) or abs(norm - G_M_S2) > self.tolerance * G_M_S2:
            self.rejected += 1
            return
        down = -(self.rotation @ a)
        if self._mean is None or self._t_last is None:
            self._mean = down
        else:
            dt = min(max(t - self._t_last, 0.0), 10.0 * self.time_constant_s)
            alpha = 1.0 - math.exp(-dt / self.time_constant_s) if dt > 0 else 1.0 / (self.accepted + 1)
            self._mean = self._mean + alpha * (down - self._mean)
        self._t_last = t if self._t_last is None else max(self._t_last, t)
        self.accepted += 1


def propagate(v: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """A direction fixed in the room, ``v`` in the axes of a camera that then turns at the constant rate
    ``omega`` (rad/s, the camera's axes, right-handed) for ``dt`` seconds: ``v`` in the camera's new axes
    (dv/dt = -omega x v: turned by |omega| dt about -omega, Rodrigues' formula)."""
    omega = np.asarray(omega, dtype=np.float64)
    speed = float(np.linalg.norm(omega))
    angle = speed * dt
    if not angle > 0.0:
        return np.asarray(v, dtype=np.float64)
    k = omega / speed
    c, s = math.cos(angle), math.sin(angle)
    return v * c - np.cross(k, v) * s + k * float(k @ v) * (1.0 - c)


def accel_profile(rs: Any, sensor: Any, stream: Any = None) -> Any | None:
    """The accelerometer stream profile of ``sensor`` at its lowest rate (motion_xyz32f), or None; with
    ``stream`` (``rs.stream.gyro``) that motion stream's instead."""
    kind = rs.stream.accel if stream is None else stream
    best = None
    for p in sensor.get_stream_profiles():
        if p.stream_type() == kind and p.format() == rs.format.motion_xyz32f:
            if best is None or p.fps() < best.fps():
                best = p
    return best


def find_accel(rs: Any, device: Any) -> tuple[Any, Any] | None:
    """(sensor, profile) of the device's accelerometer, or None when it has none (a D435, a D415)."""
    for sensor in device.query_sensors():
        profile = accel_profile(rs, sensor)
        if profile is not None:
            return sensor, profile
    return None


def find_gyro(rs: Any, sensor: Any) -> Any | None:
    """The gyro stream profile of the accelerometer's ``sensor`` at its lowest rate (200 Hz on a D435i), or
    None (a recording or device with an accelerometer only)."""
    return accel_profile(rs, sensor, rs.stream.gyro)


def sample_sink(rs: Any, estimate: GravityEstimate) -> Callable[[Any], None]:
    """A librealsense frame callback that adds each accelerometer and gyro frame to ``estimate`` (other frames
    ignored); frame timestamps are milliseconds."""
    def on_frame(frame: Any) -> None:
        kind = frame.get_profile().stream_type()
        if kind == rs.stream.accel:
            m = frame.as_motion_frame().get_motion_data()
            estimate.add(float(frame.get_timestamp()) / 1000.0, m.x, m.y, m.z)
        elif kind == rs.stream.gyro:
            m = frame.as_motion_frame().get_motion_data()
            estimate.add_gyro(float(frame.get_timestamp()) / 1000.0, m.x, m.y, m.z)
    return on_frame


def rotation_of(extrinsics: Any) -> np.ndarray:
    """librealsense extrinsics' rotation (9 values, column-major) as a 3 x 3 matrix acting on column vectors."""
    return np.asarray(extrinsics.rotation, dtype=np.float64).reshape(3, 3).T
