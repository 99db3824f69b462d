"""Real motion as MediaPipe-like landmarks: CMU BVH clips seen by virtual pinhole cameras all around the person.

Nothing here renders the fit's humanoid: the 3D points are the mocap skeleton's own joints
(:func:`bench.bvh.cmu_landmark_world`), so the proportions and the joint centres are the mocap subject's,
not the model's. In particular the hip landmarks are the mocap's hip joint centres (``LeftHip`` /
``RightHip``, 0.137 m apart for subject 131), while BlazePose's hip landmarks sit lateral of and above the
anatomical hip centres and the model's hip width is 0.115 H (0.18 m for this subject): that mismatch is the
point of an out-of-domain test. Face landmarks are offsets from the mocap head joint and its end site, heels
and foot indices from the ankle and toe joints (see :mod:`bench.bvh`).

* :func:`load_clip`: a BVH file -> :class:`MocapClip` (world points, metres, z up, every source frame).
* :meth:`MocapClip.resample`: positions linearly interpolated at ``fps`` from the clip's own rate.
* :func:`look_at_camera`, :func:`choose_distance`: a level-ish pinhole camera ``distance_m`` from the middle
  of the clip's path at an azimuth measured from the walking direction (0 = in front of the walker, 90 = on
  the walker's left), at ``CAMERA_HEIGHT_M`` aiming at ``AIM_HEIGHT_M``; the distance is the smallest of
  ``DISTANCES_M`` that keeps every landmark of every frame inside the image.
* :func:`project`: camera-frame points (33, 3) -> (33, 5) ``[x_px, y_px, z, visibility, presence]`` like
  :func:`bench.simulate.render` (z: depth relative to the mid-hip on the x pixel scale; visibility 0.99
  inside the image, 0.05 outside), with optional Gaussian pixel noise or given pixel errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from posed.bench.bvh import cmu_landmark_world, read_bvh
from posed.camera_model import Intrinsics
from posed.landmarks import LANDMARK_NAMES

CLIPS = ("131_01", "131_02")
IMAGE_SIZE = (640, 480)
FOCAL_PX = 600.0                 # 56 deg horizontal field of view at 640 px
CAMERA_HEIGHT_M = 1.2            # camera above the floor
AIM_HEIGHT_M = 0.8               # the optical axis passes this high above the middle of the path
DISTANCES_M = tuple(float(d) for d in np.arange(2.5, 5.001, 0.25))
MARGIN_PX = 4.0                  # every landmark at least this far inside the image
NOSE_HEIGHT = 0.93               # nose height / body height (as bench.falls estimates the CMU subject's height)
BODY12 = ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
          "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle")
_IDX = {n: i for i, n in enumerate(LANDMARK_NAMES)}
BODY12_IDX = np.array([_IDX[n] for n in BODY12])


def intrinsics() -> Intrinsics:
    w, h = IMAGE_SIZE
    return Intrinsics(FOCAL_PX, FOCAL_PX, w / 2.0, h / 2.0, w, h)


@dataclass(frozen=True)
class MocapClip:
    """A clip's world points: ``points[f, i]`` for the 33 MediaPipe landmarks (``LANDMARK_NAMES`` order),
    metres, z up, floor at z = 0 on the first frame, at times ``times[f]`` (s, from 0)."""

    name: str
    times: np.ndarray        # (F,)
    points: np.ndarray       # (F, 33, 3)
    source_fps: float
    height_m: float          # body height estimated from the standing nose height

    @property
    def duration_s(self) -> float:
        return float(self.times[-1])

    def resample(self, fps: float, max_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(times, points)`` at ``fps`` from t = 0 to the clip's end (or ``max_s``), positions linearly
        interpolated between the two nearest source frames."""
        end = self.duration_s if max_s is None else min(self.duration_s, max_s)
        t = np.arange(0.0, end + 1e-9, 1.0 / fps)
        u = np.clip(t * self.source_fps, 0.0, len(self.times) - 1.0)
        i0 = np.floor(u).astype(int)
        i1 = np.minimum(i0 + 1, len(self.times) - 1)
        w = (u - i0)[:, None, None]
        return t, (1.0 - w) * self.points[i0] + w * self.points[i1]

    def path(self) -> tuple[np.ndarray, np.ndarray]:
        """The middle of the mid-hip's ground path (x, y) and the unit walking direction (first -> last)."""
        mid = 0.5 * (self.points[:, _IDX["left_hip"], :2] + self.points[:, _IDX["right_hip"], :2])
        centre = 0.5 * (mid.min(axis=0) + mid.max(axis=0))
        heading = mid[-1] - mid[0]
        n = float(np.linalg.norm(heading))
        return centre, (heading / n if n > 1e-6 else np.array([1.0, 0.0]))


def load_clip(path: str | Path) -> MocapClip:
    """Read a CMU BVH clip; raises FileNotFoundError naming where the clips live."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing: the CMU clips live in shared/data/mocap/cmu "
                                "(set POSED_SHARED_DATA or run from the project root)")
    motion = read_bvh(path)
    world = cmu_landmark_world(motion)
    pts = np.array([[p[n] for n in LANDMARK_NAMES] for p in world], dtype=np.float64)
    times = np.arange(len(world)) * motion.frame_time
    height = float(pts[:5, _IDX["nose"], 2].max()) / NOSE_HEIGHT
    return MocapClip(path.stem, times, pts, motion.fps, height)


@dataclass(frozen=True)
class LookAtCamera:
    """A pinhole camera in the mocap world aimed at a point (``look_at_camera``): ``rot`` rows are the camera's
    x (right), y (down), z (forward) axes. (Not ``simulate.LevelCamera``, which is placed relative to a body.)"""

    position: np.ndarray
    rot: np.ndarray
    intrinsics: Intrinsics
    azimuth_deg: float
    distance_m: float

    @property
    def tilt_deg(self) -> float:
        """Downward tilt of the optical axis (degrees)."""
        return math.degrees(math.asin(-float(self.rot[2, 2])))

    def to_camera(self, p_world: np.ndarray) -> np.ndarray:
        return (np.asarray(p_world, float) - self.position) @ self.rot.T


def look_at_camera(centre_xy: np.ndarray, heading_xy: np.ndarray, azimuth_deg: float, distance_m: float,
                   height_m: float = CAMERA_HEIGHT_M, aim_height_m: float = AIM_HEIGHT_M,
                   k: Intrinsics | None = None) -> LookAtCamera:
    """A camera ``distance_m`` (horizontally) from ``centre_xy`` at ``azimuth_deg`` from the walking direction
    (counter-clockwise seen from above: 90 = the walker's left), looking at the centre ``aim_height_m`` high;
    no roll (image x stays horizontal)."""
    a = math.radians(azimuth_deg)
    h = np.asarray(heading_xy, float)
    left = np.array([-h[1], h[0]])
    pos = np.array([*(np.asarray(centre_xy, float) + distance_m * (math.cos(a) * h + math.sin(a) * left)), height_m])
    target = np.array([*np.asarray(centre_xy, float), aim_height_m])
    fwd = target - pos
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return LookAtCamera(pos, np.stack([right, down, fwd]), k or intrinsics(), float(azimuth_deg), float(distance_m))


def in_view(cam: LookAtCamera, points_world: np.ndarray, margin_px: float = MARGIN_PX) -> bool:
    """Every point of every frame in front of the camera and ``margin_px`` inside the image."""
    pc = cam.to_camera(points_world)
    if (pc[..., 2] <= 0.3).any():
        return False
    uv = cam.intrinsics.project(pc)
    w, h = cam.intrinsics.size
    return bool(((uv[..., 0] >= margin_px) & (uv[..., 0] <= w - 1 - margin_px)
                 & (uv[..., 1] >= margin_px) & (uv[..., 1] <= h - 1 - margin_px)).all())


def choose_distance(clip: MocapClip, azimuth_deg: float, distances: tuple[float, ...] = DISTANCES_M) -> LookAtCamera:
    """The nearest camera (of ``distances``) at this azimuth that keeps the whole clip in the image; the
    farthest one when none does (the caller reports the fraction of points outside)."""
    centre, heading = clip.path()
    pts = clip.points[::4]
    cam = None
    for d in distances:
        cam = look_at_camera(centre, heading, azimuth_deg, d)
        if in_view(cam, pts):
            return cam
    assert cam is not None
    return cam


def project(points_cam: np.ndarray, k: Intrinsics, noise_px: float = 0.0,
            rng: np.random.Generator | None = None, offset_px: np.ndarray | None = None) -> np.ndarray:
    """(33, 3) camera-frame points (m) -> (33, 5) landmarks ``[x_px, y_px, z, visibility, presence]``.

    z: depth relative to the mid-hip (middle of the two hip landmarks) times ``fx / z_midhip`` (the x pixel
    scale, negative nearer: as MediaPipe and :func:`bench.simulate.render`); visibility and presence 0.99
    inside the image, 0.05 outside; ``noise_px``: Gaussian noise on x and y (needs ``rng``); ``offset_px``:
    given pixel errors (33 x 2) added instead (noise drawn elsewhere, e.g. correlated in time)."""
    p = np.asarray(points_cam, float)
    root_z = 0.5 * (p[_IDX["left_hip"], 2] + p[_IDX["right_hip"], 2])
    uv = k.project(p)
    x, y = uv[:, 0], uv[:, 1]
    if offset_px is not None:
        x = x + offset_px[:, 0]
        y = y + offset_px[:, 1]
    elif noise_px > 0:
        assert rng is not None
        x = x + rng.normal(0.0, noise_px, size=33)
        y = y + rng.normal(0.0, noise_px, size=33)
    z = k.fx / root_z * (p[:, 2] - root_z)
    w, h = k.size
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    vis = np.where(inside, 0.99, 0.05)
    return np.column_stack([x, y, z, vis, vis])


def truth_joints(points_cam: np.ndarray) -> np.ndarray:
    """The 12 body joints (``BODY12`` order, the fit's ``joints_3d`` names), camera frame, mid-hip origin."""
    p = np.asarray(points_cam, float)
    mid = 0.5 * (p[_IDX["left_hip"]] + p[_IDX["right_hip"]])
    return p[BODY12_IDX] - mid
