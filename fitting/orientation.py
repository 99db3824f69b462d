"""Body orientation seeds from the hips and shoulders, assuming a straight lumbar spine. numba, ``cache=True``.

The hip line (averaged with the shoulder line) gives the pelvis's left axis and mid-hip -> mid-shoulder the
torso's up axis, each up to the sign of its depth (the orthographic mirror); their orthogonality fixes one
sign from the other when the left axis leaves the image plane enough. Each pair of signs is one seed: the
body angles of those axes (fitting.kinematics.body_angles_from_rotation, the same arithmetic), the limbs straight
down, gamma 1, clipped to the search box. Normalized image units (fitting.problem); angles in radians.

One call per frame (image mode and video mode's analytic starts); the plain-Python function it replaces is
its reference in ``tests/fitting/test_orientation.py``, which checks them equal to the last bit.
"""

from __future__ import annotations

import math

from numba import njit

from posed.fitting import layout as L
from posed.fitting.rotations import level_rot

MAX_SEEDS = 4
# R0 is a signed permutation: row i of R0^T R_CB is s times row k of R_CB, (k, s) = R0T_ROWS[i]
# (tested against fitting.kinematics.R0)
R0T_ROWS = ((2, -1.0), (0, 1.0), (1, -1.0))


@njit(cache=True)
def _entry(ex, ey, ez, i, j):
    """(R0^T R_CB)[i, j] for R_CB = [ex ey ez] (columns); ``0.0 +`` turns a -0 into +0 as NumPy's sum does."""
    k, s = R0T_ROWS[i]
    col = ex if j == 0 else (ey if j == 1 else ez)
    return 0.0 + s * col[k]


@njit(cache=True)
def _seed(ex, ey, ez, lo, hi, out):
    """``out`` (19) = the seed of pelvis axes ``ex, ey, ez`` (camera axes, unit): fitting.kinematics's
    ``body_angles_from_rotation`` (degrees) in radians, every other angle 0, gamma 1, clipped to [lo, hi]."""
    sq = max(-1.0, min(1.0, _entry(ex, ey, ez, 2, 1)))
    q = math.asin(sq)
    if abs(math.cos(q)) < 1e-9:
        t = 0.0
        s = math.atan2(_entry(ex, ey, ez, 1, 0), _entry(ex, ey, ez, 0, 0))
    else:
        s = math.atan2(-_entry(ex, ey, ez, 0, 1), _entry(ex, ey, ez, 1, 1))
        t = math.atan2(-_entry(ex, ey, ez, 2, 0), _entry(ex, ey, ez, 2, 2))
    deg = math.pi / 180.0
    for k in range(L.N_VAR):
        out[k] = 0.0
    out[0] = 1.0
    out[L.X_TBD] = math.degrees(t) * deg
    out[L.X_PBD] = -math.degrees(q) * deg
    out[L.X_SBD] = math.degrees(s) * deg
    for k in range(L.N_VAR):
        out[k] = min(max(out[k], lo[k]), hi[k])


@njit(cache=True)
def _to_level(r, e):
    """R_CL^T e: camera-axes vector ``e`` in the level frame ``r`` (R_CL, row-major)."""
    return (r[0] * e[0] + r[3] * e[1] + r[6] * e[2], r[1] * e[0] + r[4] * e[1] + r[7] * e[2],
            r[2] * e[0] + r[5] * e[1] + r[8] * e[2])


@njit(cache=True)
def orientation_seeds_into(obs, w, h, hip_half, shoulder_half, trunk, lo, hi, level, out):
    """The seeds of one frame into ``out`` (MAX_SEEDS x 19); returns how many (0 without both hips and both
    shoulders). ``obs``: the 12 body landmarks' x, y in turn (24, normalized units); ``w``: their weights;
    ``h``, ``hip_half``, ``shoulder_half``, ``trunk``: the body height and those lengths (metres); ``lo``,
    ``hi``: the search box (19, kernel units); ``level``: the level frame (fitting.layout.D_LEVEL's 10 values,
    flag first), against which the body angles are taken."""
    r = level_rot(level, 0)
    if not (w[0] > 0 and w[1] > 0 and w[6] > 0 and w[7] > 0):
        return 0
    o = obs
    # left axis, projected (unit length if parallel): the hips' and the shoulders' averaged; up axis likewise
    a0 = 0.5 * ((o[12] - o[14]) * h / (2 * hip_half) + (o[0] - o[2]) * h / (2 * shoulder_half))
    a1 = 0.5 * ((o[13] - o[15]) * h / (2 * hip_half) + (o[1] - o[3]) * h / (2 * shoulder_half))
    b0 = (0.5 * (o[0] + o[2]) - 0.5 * (o[12] + o[14])) * h / trunk
    b1 = (0.5 * (o[1] + o[3]) - 0.5 * (o[13] + o[15])) * h / trunk
    na = math.hypot(a0, a1)
    nb = math.hypot(b0, b1)
    ab = a0 * b0 + a1 * b1
    ya_mag = math.sqrt(max(0.0, 1.0 - min(na, 1.0) * min(na, 1.0)))
    zb_mag = math.sqrt(max(0.0, 1.0 - min(nb, 1.0) * min(nb, 1.0)))
    n = 0
    for c in range(MAX_SEEDS):
        ya = ya_mag if c < 2 else -ya_mag   # candidates (ya, zb): per sign of ya, one zb or both
        if ya_mag > 0.2:
            if c % 2 == 1:
                continue
            zb = math.copysign(zb_mag, -ab / ya)   # orthogonality a.b + ya zb = 0 fixes the sign of zb
        else:
            zb = zb_mag if c % 2 == 0 else -zb_mag
        ny = math.sqrt(a0 * a0 + a1 * a1 + ya * ya)
        if ny < 1e-6:
            continue
        ey = (a0 / ny, a1 / ny, ya / ny)
        dot = b0 * ey[0] + b1 * ey[1] + zb * ey[2]
        ez = (b0 - dot * ey[0], b1 - dot * ey[1], zb - dot * ey[2])
        nz = math.sqrt(ez[0] * ez[0] + ez[1] * ez[1] + ez[2] * ez[2])
        if nz < 1e-6:
            continue
        ez = (ez[0] / nz, ez[1] / nz, ez[2] / nz)
        ex = (ey[1] * ez[2] - ey[2] * ez[1], ey[2] * ez[0] - ey[0] * ez[2], ey[0] * ez[1] - ey[1] * ez[0])
        if level[0] != 0.0:   # the pelvis axes in the level frame: R_CL^T e
            ex, ey, ez = _to_level(r, ex), _to_level(r, ey), _to_level(r, ez)
        _seed(ex, ey, ez, lo, hi, out[n])
        n += 1
    return n
