"""Which way is down for the fit: the level frame L of a tilted camera.

The fit's pelvis-tilt prior and its centre-of-mass-over-feet term both need "down". Without more, the camera's
own +y is taken for it (the camera is assumed level). A camera tilted down by tau then splits the one thing
no landmark measures -- the pelvis tilt, traded against lumbar and hip flexion (fitting.kinematics) -- by tau:
a person seated at 90 degrees reads hips 90 - tau and a lumbar flexion of tau (docs/bench/fit.md, "Which way
is down, given to the fit"), and the centre of mass is held over the feet along the wrong line.

Given the direction of gravity in the camera's axes (an IMU's, or a measured mount's tilt and roll), the
fit takes its body angles (theta_bd, phi_bd, psi_bd) against the level frame instead:

* L: y_L along gravity (down); x_L the camera's x made level (its part orthogonal to gravity); z_L = x_L x y_L.
  R_CL (columns x_L, y_L, z_L in camera axes) is the identity for a level camera.
* the model: R_CB = R_CL R0 Rz(psi_bd) Rx(-phi_bd) Ry(theta_bd) (fitting.rotations.level_rot, in the
  kernels' data at fitting.layout.D_LEVEL).

What a FitResult reports is unchanged in meaning: its body angles are converted back to the camera
(:func:`camera_body_angles`), its joints are in camera axes, and its joint angles never depended on the frame.
Angles in this module: radians in kernel vectors, degrees where fitting.kinematics takes them.
"""

from __future__ import annotations

import math

import numpy as np

from posed.fitting import layout as L
from posed.fitting.kinematics import body_angles_from_rotation, body_rotation

# a gravity this close to the camera's x axis leaves x_L undefined by it: z_L is made level instead
_MIN_LEVEL_NORM = 1e-3
# a level frame this close to the camera's own (every entry within it) is the camera's (no rotation at all)
_IDENTITY_TOL = 1e-12


def level_frame(gravity) -> np.ndarray | None:
    """R_CL (3 x 3, camera axes of the level frame's x, y = down, z) for ``gravity``, the direction of gravity
    in the camera's axes (x right, y down, z forward; any length), or None when the camera is level (gravity
    along +y) or ``gravity`` is None.

    Raises ValueError for anything but three finite numbers not all zero."""
    if gravity is None:
        return None
    try:
        g = np.asarray(gravity, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        g = np.zeros(0)
    n = float(np.linalg.norm(g)) if g.shape == (3,) else 0.0
    if g.shape != (3,) or not np.isfinite(g).all() or not n > 0.0:
        raise ValueError(f"gravity must be 3 finite numbers, not all 0 (down in the camera's axes), got {gravity!r}")
    y = g / n
    x = np.array([1.0, 0.0, 0.0]) - y[0] * y
    if np.linalg.norm(x) < _MIN_LEVEL_NORM:   # gravity along the camera's x: keep z_L level instead
        z = np.array([0.0, 0.0, 1.0]) - y[2] * y
        z /= np.linalg.norm(z)
        x = np.cross(y, z)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)
    r = np.column_stack((x, y, z))
    return None if np.abs(r - np.eye(3)).max() <= _IDENTITY_TOL else r


def level_data(r_cl: np.ndarray | None) -> np.ndarray:
    """The 10 values of fitting.layout.D_LEVEL for ``r_cl`` (None: a level camera, all zeros)."""
    out = np.zeros(10)
    if r_cl is not None:
        out[0] = 1.0
        out[1:] = np.asarray(r_cl, dtype=np.float64).reshape(9)
    return out


def _body(x: np.ndarray) -> np.ndarray:
    return body_rotation(math.degrees(x[L.X_TBD]), math.degrees(x[L.X_PBD]), math.degrees(x[L.X_SBD]))


def _set_body(x: np.ndarray, r: np.ndarray) -> np.ndarray:
    t, p, s = body_angles_from_rotation(r)
    out = np.array(x, dtype=np.float64)
    out[L.X_TBD], out[L.X_PBD], out[L.X_SBD] = math.radians(t), math.radians(p), math.radians(s)
    return out


def camera_body_angles(x: np.ndarray, r_cl: np.ndarray | None) -> np.ndarray:
    """A copy of solution ``x`` (kernel units) whose body angles, taken against the level frame ``r_cl``, are
    taken against the camera instead (the same R_CB: every point where it was)."""
    if r_cl is None:
        return np.array(x, dtype=np.float64)
    return _set_body(x, np.asarray(r_cl) @ _body(x))


def reexpress(x: np.ndarray, r_old: np.ndarray | None, r_new: np.ndarray | None) -> np.ndarray:
    """``x`` with its body angles, taken against level frame ``r_old``, taken against ``r_new`` (None: the
    camera's own): the same body in the camera, for a fit whose down changed between frames. ``x`` itself when
    the frame did not change, else a copy."""
    if r_old is None and r_new is None:
        return x
    a = np.eye(3) if r_old is None else np.asarray(r_old)
    b = np.eye(3) if r_new is None else np.asarray(r_new)
    if np.array_equal(a, b):
        return x
    return _set_body(x, b.T @ a @ _body(x))
