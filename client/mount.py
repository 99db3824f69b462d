"""Where the camera is: the ``posed.camera_mount`` message the robot's own software puts on
``posed/ROBOT/camera/mount`` (docs/formats.md), and the geometry a robot needs to fill it from its transforms.

* :func:`camera_mount_message` builds one message from keyword arguments and checks it (``ValueError`` naming
  the argument, what is wrong and what it may be), then checks it against the shipped schema;
  :meth:`client.PosedClient.set_camera_mount` puts what it returns.
* :func:`mount_from_rotation` turns the camera's orientation (a camera-from-world rotation matrix, world z up)
  and the camera's height in that world into the message's ``down`` and ``height_m``;
  :func:`quaternion_matrix` is the rotation matrix of a unit quaternion ``(x, y, z, w)`` (the order of ROS's
  ``geometry_msgs/Quaternion``). docs/ros2.md feeds them from tf2.

Axes: the camera's optical frame, x image right, y image down, z forward (posed's camera axes, ROS's
``*_optical_frame``). Tilt and roll follow ``falls.camera_tilt_deg``/``camera_roll_deg``: pitched down
positive, rolled clockwise in the image positive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from posed.client import contract

FORMAT = "posed.camera_mount"
KEY = "camera/mount"                  # under posed/ROBOT/
HEIGHT_M = (0.05, 5.0)
ANGLE_DEG = (-90.0, 90.0)
VALID_S = (0.05, 3600.0)
DEFAULT_VALID_S = 1.0
MIN_DOWN = 1e-9                       # the shortest down vector that still gives a direction
SOURCE_CHARS = 128
ROTATION_TOL = 1e-3                   # how far from a rotation (R^T R - I, det - 1) a given matrix may be


class CameraMount(NamedTuple):
    """The message's ``down`` (a unit vector in the camera's axes) and ``height_m`` (None: not known)."""

    down: tuple[float, float, float]
    height_m: float | None


def _finite(name: str, value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name}={value!r}: give {what}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name}={value!r} is not finite: give {what}")
    return v


def _in_range(name: str, value, lo: float, hi: float, what: str) -> float:
    v = _finite(name, value, f"{what} from {lo:g} to {hi:g}")
    if not lo <= v <= hi:
        raise ValueError(f"{name}={value!r} is outside {lo:g}..{hi:g}: give {what} from {lo:g} to {hi:g}")
    return v


def _down(value) -> list[float]:
    what = "[x, y, z]: gravity in the camera's axes (x image right, y image down, z forward), not all 0"
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"down={value!r}: give {what}") from None
    if len(items) != 3:
        raise ValueError(f"down={value!r} has {len(items)} values: give {what}")
    out = [_finite(f"down[{i}]", v, f"three finite numbers, down={what}") for i, v in enumerate(items)]
    if not math.hypot(*out) > MIN_DOWN:           # the daemon reads a shorter one as no direction
        raise ValueError(f"down={value!r} has no direction (all 0, or shorter than {MIN_DOWN:g}): give {what}")
    return out


def camera_mount_message(*, down: Sequence[float] | None = None, tilt_deg: float | None = None,
                         roll_deg: float | None = None, height_m: float | None = None,
                         valid_s: float = DEFAULT_VALID_S, time_unix: float | None = None,
                         source: str | None = None) -> dict:
    """One ``posed.camera_mount`` message: ``down`` (gravity in the camera's axes) or ``tilt_deg`` and
    ``roll_deg`` (both), ``height_m`` optional; ``time_unix`` None leaves it out (the daemon takes the time it
    receives the message). Raises ``ValueError`` naming what is wrong and the valid choices."""
    msg: dict = {"format": FORMAT, "version": 1}
    if down is not None and (tilt_deg is not None or roll_deg is not None):
        raise ValueError("give down=[x, y, z] or tilt_deg and roll_deg, not both")
    if down is not None:
        msg["down"] = _down(down)
    elif tilt_deg is not None and roll_deg is not None:
        msg["tilt_deg"] = _in_range("tilt_deg", tilt_deg, *ANGLE_DEG, "degrees, pitched down positive,")
        msg["roll_deg"] = _in_range("roll_deg", roll_deg, *ANGLE_DEG, "degrees, clockwise in the image positive,")
    elif tilt_deg is not None or roll_deg is not None:
        given, other = ("tilt_deg", "roll_deg") if tilt_deg is not None else ("roll_deg", "tilt_deg")
        raise ValueError(f"{given} without {other}: give both (0.0 for a camera level that way), or down=[x, y, z]")
    else:
        raise ValueError("give down=[x, y, z] (gravity in the camera's axes) or tilt_deg and roll_deg")
    if height_m is not None:
        msg["height_m"] = _in_range("height_m", height_m, *HEIGHT_M,
                                    "metres of the camera's optical centre above the floor")
    msg["valid_s"] = _in_range("valid_s", valid_s, *VALID_S, "seconds the pose holds after time_unix")
    if time_unix is not None:
        msg["time_unix"] = _finite("time_unix", time_unix, "unix seconds when the pose was true, or None (now)")
        if msg["time_unix"] <= 0:
            raise ValueError(f"time_unix={time_unix!r}: give unix seconds (time.time()), or None for when received")
    if source is not None:
        if not isinstance(source, str) or len(source) > SOURCE_CHARS or not source.isprintable():
            raise ValueError(f"source={source!r:.60}: give free text (a str) of at most {SOURCE_CHARS} printable "
                             "characters, or None")
        msg["source"] = source
    problems = contract.errors(msg)
    if problems:                       # a guard: the checks above should have said it first
        raise ValueError(f"not a valid {FORMAT}: {'; '.join(problems)}")
    return msg


def quaternion_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    """The 3x3 rotation matrix of the quaternion ``(x, y, z, w)`` (normalised first). For a tf2 transform
    looked up as ``(target=world, source=camera)`` it is world-from-camera: its columns are the camera's axes
    in the world."""
    q = np.array([x, y, z, w], float)
    n = float(np.linalg.norm(q))
    if not math.isfinite(n) or n < 1e-9:
        raise ValueError(f"quaternion {(x, y, z, w)!r}: give four finite numbers, not all 0")
    x, y, z, w = q / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def mount_from_rotation(camera_from_world, camera_z_m: float | None = None,
                        floor_z_m: float = 0.0) -> CameraMount:
    """The message's ``down`` and ``height_m`` for a camera whose orientation is ``camera_from_world`` (3x3:
    a vector in world axes, world z up, to the camera's optical axes) at height ``camera_z_m`` in that world,
    over a floor at ``floor_z_m`` (``camera_z_m`` None: height not known). Down is the world's -z seen from the
    camera: ``-camera_from_world[:, 2]``."""
    r = np.asarray(camera_from_world, float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"camera_from_world: give a 3x3 rotation matrix of finite numbers, got shape {r.shape}")
    if np.abs(r.T @ r - np.eye(3)).max() > ROTATION_TOL or abs(np.linalg.det(r) - 1.0) > ROTATION_TOL:
        raise ValueError("camera_from_world is not a rotation (orthonormal, determinant +1): give the rotation "
                         "part of the transform, e.g. quaternion_matrix(...).T")
    down = -r[:, 2]
    down = down / np.linalg.norm(down)
    height = None if camera_z_m is None else float(camera_z_m) - float(floor_z_m)
    return CameraMount(tuple(float(v) + 0.0 for v in down), height)   # + 0.0: no -0.0
