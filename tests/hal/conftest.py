"""Shared fixtures of the hal tests: the real squat video and a RealSense recording made from it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest

from posed.camera_model import Intrinsics

SQUAT_FRAMES = 65
SQUAT_FPS = 5.0


@pytest.fixture(scope="session")
def squat_video(shared_data: Path) -> Path:
    path = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    assert path.is_file(), f"missing real test video {path}"
    return path


@pytest.fixture(scope="session")
def squat_frames(squat_video: Path) -> list[np.ndarray]:
    """Every frame of the squat video decoded once with plain OpenCV (the reference for the sources)."""
    cap = cv2.VideoCapture(str(squat_video), cv2.CAP_FFMPEG)
    frames = []
    while True:
        ok, image = cap.read()
        if not ok:
            break
        frames.append(image)
    cap.release()
    assert len(frames) == SQUAT_FRAMES
    return frames


# The synthetic RGB-D camera of the .db3 recording: colour is the squat video at 360x640 (portrait), depth a
# half-resolution stream with half the focal length, 15 mm to the left of the colour camera (like a D435).
COLOUR_K = Intrinsics(fx=420.0, fy=421.0, cx=181.0, cy=318.0, width=360, height=640)
DEPTH_K = Intrinsics(fx=210.0, fy=210.5, cx=89.75, cy=158.75, width=180, height=320)
DEPTH_TO_COLOUR_T = (0.015, 0.0, 0.0)
DEPTH_SCALE = 0.001
WALL_MM, BOX_MM = 3000, 1500
DB3_FRAMES = 6
TS0_MS = 1000.0


def box_rect(i: int) -> tuple[int, int, int, int]:
    """Depth-pixel rectangle (v0, v1, u0, u1) of the near box in frame i (it moves 4 px right per frame)."""
    return 90, 230, 50 + 4 * i, 110 + 4 * i


def synthetic_depth(i: int) -> np.ndarray:
    depth = np.full((DEPTH_K.height, DEPTH_K.width), WALL_MM, np.uint16)
    v0, v1, u0, u1 = box_rect(i)
    depth[v0:v1, u0:u1] = BOX_MM
    return depth


def colour_frames(squat_frames: list[np.ndarray], first: int, n: int) -> tuple[list[np.ndarray], list[float]]:
    """``n`` squat frames from ``first`` at the recording's colour size, and their times (ms from the first)."""
    colour = [cv2.resize(f, (COLOUR_K.width, COLOUR_K.height), interpolation=cv2.INTER_AREA)
              for f in squat_frames[first:first + n]]
    return colour, [i * 1000.0 / SQUAT_FPS for i in range(n)]


@dataclass(frozen=True)
class Db3Recording:
    path: Path
    colour: list[np.ndarray]      # BGR frames as recorded
    pts_ms: list[float]


@pytest.fixture(scope="session")
def squat_db3(tmp_path_factory: pytest.TempPathFactory, squat_frames: list[np.ndarray]) -> Db3Recording:
    """A small RealSense recording made by pyrealsense2's software device + recorder from the real video."""
    from posed.hal.db3 import Db3Writer

    path = tmp_path_factory.mktemp("db3") / "squat.db3"
    colour, pts = colour_frames(squat_frames, 10, DB3_FRAMES)
    rotation = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    with Db3Writer(path, COLOUR_K, SQUAT_FPS, depth_scale=DEPTH_SCALE, depth_intrinsics=DEPTH_K,
                   depth_to_colour=(rotation, DEPTH_TO_COLOUR_T), serial="000000000042", name="squat test") as w:
        for i, image in enumerate(colour):
            w.write(image, synthetic_depth(i), TS0_MS + pts[i], i)
    assert path.stat().st_size > 0
    return Db3Recording(path, colour, pts)


# The RealSense recording with an accelerometer (a D435i's "Motion Module"): the squat video's colour, and
# accelerometer samples at ACCEL_HZ of a camera tilted IMU_TILT_DEG down and rolled IMU_ROLL_DEG, with noise
# and a few bumps (samples far from 1 g that the filter must skip).
IMU_TILT_DEG, IMU_ROLL_DEG = 20.0, -3.0
IMU_FRAMES = 15
ACCEL_HZ = 100
ACCEL_NOISE_M_S2 = 0.05     # per axis, about the BMI055's at 63 Hz (datasheet: 150 ug/sqrt(Hz))


def imu_down(tilt_deg: float = IMU_TILT_DEG, roll_deg: float = IMU_ROLL_DEG) -> np.ndarray:
    from posed.falls.features import gravity_from_tilt

    return np.asarray(gravity_from_tilt(tilt_deg, roll_deg), dtype=np.float64)


@pytest.fixture(scope="session")
def squat_imu_db3(tmp_path_factory: pytest.TempPathFactory, squat_frames: list[np.ndarray]) -> Db3Recording:
    """Colour (the real squat video) + accelerometer, recorded by pyrealsense2's software device + recorder."""
    from posed.hal.db3 import Db3Writer
    from posed.hal.imu import G_M_S2

    path = tmp_path_factory.mktemp("imu") / "squat_imu.db3"
    colour, pts = colour_frames(squat_frames, 20, IMU_FRAMES)
    rng = np.random.default_rng(7)
    reading = -G_M_S2 * imu_down()                       # an accelerometer at rest reads the support's push
    period_ms = 1000.0 / ACCEL_HZ
    with Db3Writer(path, COLOUR_K, SQUAT_FPS, accel_fps=ACCEL_HZ, name="squat imu test") as w:
        n = 0
        for i, image in enumerate(colour):
            while n * period_ms <= pts[i]:
                sample = reading + rng.normal(0.0, ACCEL_NOISE_M_S2, 3)
                if n % 37 == 5:
                    sample = sample + np.array([0.0, 6.0, 0.0])   # a bump: |a| far from g, skipped
                w.write_accel(TS0_MS + n * period_ms, sample)
                n += 1
            w.write(image, None, TS0_MS + pts[i], i)
    return Db3Recording(path, colour, pts)
