"""The numbers a FitResult reports for a solution (fitting.assemble names them), computed in one kernel
(``cache=True``): the model's 12 joints in camera axes, every value in the unit and rounding the result
reports it in and in the result's own order, and the root's position (fitting.root).

The order (``N_REPORTED`` values): the paper's 19 variables (fitting.result.VARIABLE_NAMES; degrees, gamma
unitless), the 23 joint angles (JOINT_ANGLE_NAMES, degrees: the estimated ones from the solution, the fixed
ones from the fitter's fixed values), the 13 joints x 3 (JOINT_3D_NAMES: the mid-hip origin, then the 12
body landmarks; metres, camera axes, mid-hip origin) and the upper arms' two rotations
(SHOULDER_ROTATION_NAMES, degrees). Angles and gamma rounded to 4 decimals, the joints to
5, each as ``np.round`` does it (tested against np.round to the last bit in tests/fitting/test_assemble.py).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import forward_kinematics as FK
from posed.fitting import layout as L
from posed.fitting.result import JOINT_ANGLE_NAMES, VARIABLE_NAMES
from posed.fitting.root import root_position

# the joint angles the model holds fixed (not estimated), in the order of the fitter's fixed values
FIXED_NAMES = ("theta_hd", "psi_hd", "psi_hp_l", "psi_hp_r", "theta_an_l", "phi_an_l", "theta_an_r", "phi_an_r")

# The sources: [x (kernel units: radians, gamma unitless), the fixed angles (degrees), the 12 joints x 3
# (metres) row by row]; per source the divisor to the reported unit (degrees; gamma, the fixed angles and
# the joints' metres as they are) and 10^decimals of its rounding.
_N_SOURCES = L.N_VAR + L.N_FIXED + 3 * L.N_LM
_UNIT = np.concatenate(([1.0], np.full(L.N_VAR - 1, math.pi / 180.0), np.ones(L.N_FIXED + 3 * L.N_LM)))
_DECIMALS = np.concatenate((np.full(L.N_VAR + L.N_FIXED, 1e4), np.full(3 * L.N_LM, 1e5)))
# Where the reported values start (ANGLES, JOINTS) and per reported value its source (-1: the mid-hip's zeros)
ANGLES, JOINTS = len(VARIABLE_NAMES), len(VARIABLE_NAMES) + len(JOINT_ANGLE_NAMES)
_SOURCE = np.array([*range(len(VARIABLE_NAMES)),
                    *(L.N_VAR + FIXED_NAMES.index(n) if n in FIXED_NAMES else 4 + VARIABLE_NAMES[4:].index(n)
                      for n in JOINT_ANGLE_NAMES),
                    -1, -1, -1, *range(L.N_VAR + L.N_FIXED, _N_SOURCES), L.X_PSISH_L, L.X_PSISH_R])
ROTATIONS = len(_SOURCE) - 2   # where the upper arms' rotations (SHOULDER_ROTATION_NAMES) start
N_REPORTED = len(_SOURCE)


@njit(cache=True)
def rounded(v, unit, decimals):
    """``np.round(v / unit, log10(decimals))`` with np.round's own steps (times 10^decimals, rint, divided by
    10^decimals)."""
    return np.rint(v / unit * decimals) / decimals


@njit(cache=True)
def reported_values(x, data, fixed_deg, root_z, measured, out):
    """The reported values of solution ``x`` (kernel units) of the problem ``data`` into ``out``
    (N_REPORTED, the module docstring's order), ``fixed_deg`` the fixed angles (degrees, FIXED_NAMES order);
    returns the root's position (fitting.root.root_position: known, X, Y, Z in metres, not rounded),
    ``root_z`` the measured mid-hip depth used when ``measured``."""
    pts_b = np.empty((L.N_POINTS, 3))
    pts_c = np.empty((L.N_POINTS, 3))
    FK.model_points_into(x, data, pts_b, pts_c, FK.empty_work())
    src = np.empty(_N_SOURCES)
    src[:L.N_VAR] = x
    src[L.N_VAR:L.N_VAR + L.N_FIXED] = fixed_deg
    for i in range(L.N_LM):
        for c in range(3):
            src[L.N_VAR + L.N_FIXED + 3 * i + c] = pts_c[i, c]
    for j in range(N_REPORTED):
        k = _SOURCE[j]
        out[j] = 0.0 if k < 0 else rounded(src[k], _UNIT[k], _DECIMALS[k])
    return root_position(x, data, pts_c, root_z, measured)
