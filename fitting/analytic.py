"""Analytic starting points of the refinement: an orientation seed with every limb solved from its own 2D
landmarks. numba, ``cache=True``.

Each limb in turn (left arm, right arm, left leg, right leg; fitting.refine.LIMB_* order) is re-solved by
:func:`fitting.refine.limb_from_observation` for both depth signs of its upper segment, and the variant with
the smallest :func:`fitting.loss.pose_loss` is kept (the seed's own limb when neither is better); later limbs
are solved on top of the earlier choices. Kernel units (radians; gamma unitless).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from posed.fitting import layout as L
from posed.fitting.loss import pose_loss
from posed.fitting.refine import limb_from_observation


@njit(cache=True)
def analytic_start(seed, data, work, out):
    """``out`` (19) = ``seed`` (19) with its four limbs solved from the landmarks of ``data`` (the frame's
    packed array, fitting.problem.pack), each limb's depth sign chosen by the loss. ``work``: the loss's work
    array (fitting.forward_kinematics.empty_work)."""
    trial = np.empty(L.N_VAR)
    for k in range(L.N_VAR):
        out[k] = seed[k]
    for limb in range(4):
        best = pose_loss(out, data, work)
        best_sign = 0.0   # 0: the limb as it is
        for sign in (1.0, -1.0):
            limb_from_observation(out, data, limb, sign, trial)
            c = pose_loss(trial, data, work)
            if c < best:
                best = c
                best_sign = sign
        if best_sign != 0.0:
            limb_from_observation(out, data, limb, best_sign, trial)
            for k in range(L.N_VAR):
                out[k] = trial[k]
