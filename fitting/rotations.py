"""numba kernels: 3x3 rotations as row-major 9-tuples (no allocation in the hot loop) and the small vector
helpers the forward kinematics and the Jacobian share. ``cache=True``; angles in radians.

Axes: the pelvis (body) frame has x forward, y to the person's left, z up; camera axes have x right, y down,
z away from the camera (fitting.kinematics, docs/body-model.md). Tested through the forward kinematics
against the NumPy reference in :mod:`fitting.kinematics`.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def mm(a, b):
    """The product a b of two row-major 3x3 rotations."""
    return (a[0] * b[0] + a[1] * b[3] + a[2] * b[6], a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
            a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
            a[3] * b[0] + a[4] * b[3] + a[5] * b[6], a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
            a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
            a[6] * b[0] + a[7] * b[3] + a[8] * b[6], a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
            a[6] * b[2] + a[7] * b[5] + a[8] * b[8])


@njit(cache=True)
def rx(a):
    """Rotation by ``a`` about x."""
    c, s = math.cos(a), math.sin(a)
    return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)


@njit(cache=True)
def ry(a):
    """Rotation by ``a`` about y."""
    c, s = math.cos(a), math.sin(a)
    return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)


@njit(cache=True)
def rz(a):
    """Rotation by ``a`` about z."""
    c, s = math.cos(a), math.sin(a)
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


@njit(cache=True)
def rx_cs(c, s):
    """Rotation about x from its cosine and sine."""
    return (1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)


@njit(cache=True)
def ry_cs(c, s):
    """Rotation about y from its cosine and sine."""
    return (c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)


@njit(cache=True)
def rz_cs(c, s):
    """Rotation about z from its cosine and sine."""
    return (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)


@njit(cache=True)
def r0():
    """Camera axes of the pelvis axes in the neutral pose (fitting.kinematics.R0)."""
    return (0.0, 1.0, 0.0, 0.0, 0.0, -1.0, -1.0, 0.0, 0.0)


@njit(cache=True)
def body_rot(theta, phi, psi):
    """R_CB = R0 Rz(psi) Rx(-phi) Ry(theta): camera axes from the pelvis frame (theta_bd, phi_bd, psi_bd)."""
    return mm(mm(mm(r0(), rz(psi)), rx(-phi)), ry(theta))


@njit(cache=True)
def level_rot(data, at):
    """R_CL, the camera axes of the level frame (x level, y down along gravity, z level), from ``data[at]``
    (fitting.layout.D_LEVEL: a flag, then the 9 entries row-major); the identity when the flag is 0 (the camera
    is level)."""
    if data[at] == 0.0:
        return (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    return (data[at + 1], data[at + 2], data[at + 3], data[at + 4], data[at + 5], data[at + 6],
            data[at + 7], data[at + 8], data[at + 9])


@njit(cache=True)
def transposed(r):
    """The transpose (inverse) of rotation ``r``."""
    return (r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8])


@njit(cache=True)
def column(r, c):
    """Column ``c`` of ``r``: where ``r`` takes the unit vector of axis c."""
    return r[c], r[3 + c], r[6 + c]


@njit(cache=True)
def put_point(out, i, ox, oy, oz, r, vx, vy, vz):
    """out[i] = o + r v (a point ``v`` of a segment frame placed at ``o`` with orientation ``r``)."""
    out[i, 0] = ox + r[0] * vx + r[1] * vy + r[2] * vz
    out[i, 1] = oy + r[3] * vx + r[4] * vy + r[5] * vz
    out[i, 2] = oz + r[6] * vx + r[7] * vy + r[8] * vz
