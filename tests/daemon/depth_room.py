"""A furnished room seen by a RealSense-like RGB-D camera, for the floor-from-depth tests (issue 33 item 1a).

The room (world axes: x east, y north, z up, the floor at z = 0) is 5 m x 6 m x 2.6 m; in it a table (top at
0.75 m), a bed (0.5 m), a tall cabinet and a low box; no person. :func:`render` ray-casts the depth image (z
along the camera's axis, millimetres, with noise of 0.5 % of the range and 3 % holes, as a D435 at 1-4 m) and
a shaded colour image; :func:`write_db3` records a scene with pyrealsense2's software device and recorder
(:class:`hal.db3.Db3Writer`, as the IMU and depth tests make theirs), optionally with an accelerometer.
Generated in the test's temporary directory, never committed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from posed.bench.falls_body import WorldCamera
from posed.camera_model import Intrinsics

ROOM_LO, ROOM_HI = np.array([-2.5, -1.0, 0.0]), np.array([2.5, 5.0, 2.6])
FURNITURE = (                                     # (low corner, high corner), world metres
    (np.array([0.2, 1.8, 0.0]), np.array([1.4, 2.6, 0.75])),    # a table
    (np.array([-2.3, 2.5, 0.0]), np.array([-0.7, 4.6, 0.5])),   # a bed
    (np.array([1.8, 3.5, 0.0]), np.array([2.5, 4.1, 1.9])),     # a cabinet
    (np.array([-0.4, 1.2, 0.0]), np.array([0.0, 1.6, 0.35])),   # a low box
)
DEPTH_TO_COLOUR_T = (0.015, 0.0, 0.0)             # the depth camera 15 mm beside the colour camera (a D435)
DEPTH_SCALE = 0.001


@dataclass(frozen=True)
class Mount:
    """Where the colour camera is: its height above the floor, tilt down and roll (deg, as
    falls.features.gravity_from_tilt); the truth the tests compare with."""

    height_m: float
    tilt_deg: float
    roll_deg: float

    def camera(self, width: int, height: int, offset_x_m: float = 0.0) -> WorldCamera:
        cam = WorldCamera(x=0.3, y=-0.8, z=self.height_m, tilt=self.tilt_deg, roll=self.roll_deg, width=width,
                          height=height, hfov=69.0)
        if offset_x_m:
            c = np.array([cam.x, cam.y, cam.z]) + offset_x_m * cam.axes[0]
            cam = WorldCamera(x=float(c[0]), y=float(c[1]), z=float(c[2]), tilt=self.tilt_deg, roll=self.roll_deg,
                              width=width, height=height, hfov=69.0)
        return cam


def render(cam: WorldCamera, seed: int = 0, noise: float = 0.005, holes: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """(depth uint16 mm, colour BGR uint8) of the room seen by ``cam``."""
    k = cam.intrinsics
    v, u = np.mgrid[0:cam.height, 0:cam.width].astype(float)
    rays_c = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u)], axis=-1)   # z = 1: s is depth
    rays = rays_c @ cam.axes                                                              # world directions
    origin = np.array([cam.x, cam.y, cam.z])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / rays
        # inside the room: the nearest wall, floor or ceiling the ray leaves through
        exits = np.where(rays > 0, (ROOM_HI - origin) * inv, (ROOM_LO - origin) * inv)
        exits = np.where(np.isfinite(exits) & (exits > 0), exits, np.inf)
        s = exits.min(axis=-1)
        label = np.argmin(exits, axis=-1)                      # 0, 1: walls; 2: floor or ceiling
        for i, (lo, hi) in enumerate(FURNITURE):
            t0, t1 = (lo - origin) * inv, (hi - origin) * inv
            enter = np.nanmax(np.minimum(t0, t1), axis=-1)
            leave = np.nanmin(np.maximum(t0, t1), axis=-1)
            hit = (enter <= leave) & (enter > 0) & (enter < s)
            s = np.where(hit, enter, s)
            label = np.where(hit, 3 + i, label)
    rng = np.random.default_rng(seed)
    z = s * (1.0 + rng.normal(0.0, noise, s.shape))
    z[rng.random(s.shape) < holes] = 0.0
    depth = np.clip(np.round(z / DEPTH_SCALE), 0, 65535).astype(np.uint16)
    shade = np.array([150, 170, 90, 60, 120, 200, 80])[label].astype(float)
    shade = shade * (1.0 - 0.08 * np.clip(s, 0, 6)) + 40
    colour = np.clip(np.stack([shade, shade * 0.95, shade * 0.85], axis=-1), 0, 255).astype(np.uint8)
    return depth, colour


def write_db3(path: Path, mount: Mount, frames: int, fps: float = 15.0, width: int = 424, height: int = 240,
              accel_hz: float | None = None, accel_noise: float = 0.05) -> Path:
    """A RealSense recording of the room (colour + depth 15 mm beside it, + an accelerometer at ``accel_hz``
    reading the mount's gravity with noise when given): ``frames`` frames at ``fps``."""
    from posed.falls.features import gravity_from_tilt
    from posed.hal.db3 import IDENTITY_ROTATION, Db3Writer
    from posed.hal.imu import G_M_S2

    colour_cam = mount.camera(width, height)
    depth_cam = mount.camera(width, height, offset_x_m=DEPTH_TO_COLOUR_T[0])
    k = colour_cam.intrinsics
    colour_k = Intrinsics(k.fx, k.fy, k.cx, k.cy, width, height)
    reading = -G_M_S2 * gravity_from_tilt(mount.tilt_deg, mount.roll_deg)
    rng = np.random.default_rng(11)
    kwargs = {"accel_fps": int(accel_hz)} if accel_hz else {}
    period_ms = 1000.0 / accel_hz if accel_hz else math.inf
    n = 0
    with Db3Writer(path, colour_k, fps, depth_scale=DEPTH_SCALE, depth_intrinsics=colour_k,
                   depth_to_colour=(IDENTITY_ROTATION, DEPTH_TO_COLOUR_T), serial="000000000033",
                   name="room test", **kwargs) as w:
        for i in range(frames):
            t_ms = 1000.0 + i * 1000.0 / fps
            while accel_hz and 1000.0 + n * period_ms <= t_ms:
                w.write_accel(1000.0 + n * period_ms, reading + rng.normal(0.0, accel_noise, 3))
                n += 1
            depth, _ = render(depth_cam, seed=i)
            _, colour = render(colour_cam, seed=i, noise=0.0, holes=0.0)
            w.write(colour, depth, t_ms, i)
    return path


MOUNTS = (Mount(1.25, 28.0, -2.5), Mount(0.85, 12.0, 3.0), Mount(2.0, 35.0, 0.0), Mount(0.6, 5.0, 1.0),
          Mount(1.6, 45.0, -4.0), Mount(1.0, 20.0, 0.0))


def bench(seeds: int = 5) -> None:
    """The landmark stage's fit (daemon.stages.depth_floor) on the rendered room: its cost per fit and its
    errors, over ``MOUNTS`` x (no prior, an IMU prior 1.5 deg off) x ``seeds`` depth images, at two sizes."""
    import statistics

    from posed.daemon.stages.depth_floor import DepthFloor
    from posed.falls.features import gravity_from_tilt

    for width, height in ((640, 480), (424, 240)):
        ms, errs = [], []
        for m in MOUNTS:
            cam = m.camera(width, height)
            for prior in (None, gravity_from_tilt(m.tilt_deg + 1.5, m.roll_deg - 1.0) * 9.8):
                for seed in range(seeds):
                    depth, _ = render(cam, seed=seed)
                    floor = DepthFloor(refresh_s=0.0)
                    floor.offer(depth, DEPTH_SCALE, cam.intrinsics, prior, 0.0)
                    ms.append(floor.fit_ms)
                    f = floor.field(0.0)
                    errs.append((abs(f["height_m"] - m.height_m), abs(f["tilt_deg"] - m.tilt_deg),
                                 abs(f["roll_deg"] - m.roll_deg)) if "down" in f else (math.inf,) * 3)
        e = np.array(errs)
        print(f"{width}x{height}: {len(ms)} fits (the first cold), fit_ms median {statistics.median(ms):.2f} "
              f"p95 {np.percentile(ms, 95):.2f} max {max(ms):.2f}; worst error: height {e[:, 0].max() * 100:.2f} cm, "
              f"tilt {e[:, 1].max():.2f} deg, roll {e[:, 2].max():.2f} deg")


if __name__ == "__main__":
    bench()
