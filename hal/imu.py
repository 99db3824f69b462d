"""The direction of gravity from a camera's accelerometer (RealSense D435i, D455), in the colour camera's axes.

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

Time: samples carry the device's timestamp (seconds, the same clock as the camera's frames). ``at(t)`` uses
only the samples stamped at or before ``t`` and keeps the later ones for the next frame, so a recording gives
every frame the same gravity however fast it is played. Samples are added from librealsense's threads and read
by the frame reader: every method takes a lock.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

G_M_S2 = 9.80665            # standard gravity
TIME_CONSTANT_S = 0.5       # the low-pass: a tilt change is followed within ~3 time constants (1.5 s)
TOLERANCE = 0.2             # a sample counts when | |a| - g | <= 0.2 g (a robot braking at 2 m/s^2 does not)
MIN_SAMPLES = 10            # accepted samples before the first estimate (0.16 s at the D435i's 63 Hz)
MAX_PENDING = 4096          # samples waiting for a frame: older ones are folded in without waiting


class GravityEstimate:
    """Accelerometer samples -> the unit down vector in the colour camera's axes (module doc).

    ``rotation``: 3 x 3, turns a sample from the accelerometer's axes into the colour camera's (identity when
    the two agree)."""

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
        self._mean: np.ndarray | None = None   # low-passed down vector (m/s^2), colour axes
        self._t_last: float | None = None
        self.accepted = 0
        self.rejected = 0                      # accelerating, a bump, or not a finite reading

    def add(self, t_s: float, ax: float, ay: float, az: float) -> None:
        """One accelerometer sample: device time (s) and specific force (m/s^2, the accelerometer's axes)."""
        with self._lock:
            self._pending.append((float(t_s), float(ax), float(ay), float(az)))
            while len(self._pending) > MAX_PENDING:
                self._fold(self._pending.popleft())

    def at(self, t_s: float) -> tuple[float, float, float] | None:
        """The down direction (unit vector, colour camera axes) from the samples stamped at or before ``t_s``,
        or None while fewer than ``min_samples`` samples have been accepted."""
        with self._lock:
            while self._pending and self._pending[0][0] <= t_s:
                self._fold(self._pending.popleft())
            if self._mean is None or self.accepted < self.min_samples:
                return None
            n = float(np.linalg.norm(self._mean))
            if not n > 0:
                return None
            g = self._mean / n
            return (float(g[0]), float(g[1]), float(g[2]))

    def counters(self) -> dict[str, int]:
        with self._lock:
            return {"imu_samples": self.accepted, "imu_rejected": self.rejected}

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


def accel_profile(rs: Any, sensor: Any) -> Any | None:
    """The accelerometer stream profile of ``sensor`` at its lowest rate (motion_xyz32f), or None."""
    best = None
    for p in sensor.get_stream_profiles():
        if p.stream_type() == rs.stream.accel and p.format() == rs.format.motion_xyz32f:
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


def sample_sink(rs: Any, estimate: GravityEstimate) -> Callable[[Any], None]:
    """A librealsense frame callback that adds each accelerometer frame to ``estimate`` (other frames ignored);
    frame timestamps are milliseconds."""
    def on_frame(frame: Any) -> None:
        if frame.get_profile().stream_type() != rs.stream.accel:
            return
        m = frame.as_motion_frame().get_motion_data()
        estimate.add(float(frame.get_timestamp()) / 1000.0, m.x, m.y, m.z)
    return on_frame


def rotation_of(extrinsics: Any) -> np.ndarray:
    """librealsense extrinsics' rotation (9 values, column-major) as a 3 x 3 matrix acting on column vectors."""
    return np.asarray(extrinsics.rotation, dtype=np.float64).reshape(3, 3).T
