"""BlazePose's world landmarks as evidence of depth in the fit (issue 38).

The landmark model's world output (``LandmarkFrame.world``: 33 joints in metres, origin at the middle of the
hips, axes roughly the camera's) is a learned 3D estimate: good depth order on most limbs, a metric scale,
and an error of its own. The fit uses its depths through the robust depth term (fitting.depth_term) as a
second "sensor": each of the 12 body landmarks votes for the mid-hip's depth with its world depth, the votes'
median is the offset, and a landmark whose depth contradicts a hypothesis costs at most one unit
(Geman-McClure) -- so a frame where BlazePose is badly wrong (the tracker on the wrong body, a limb mirrored)
cannot drag the fit, and one where no hypothesis agrees with most of it is fitted without it
(:func:`fitting.depth_term.usable`). It decides between what the image cannot tell apart, a limb towards or
away from the camera, and adds refinement rows (the depth rows of fitting.jacobian) pulling each joint's
depth relative to the mid-hip towards BlazePose's.

Unlike a depth camera the world landmarks are joint centres (no surface offset) whether the joint is hidden
or not (no occlusion test), with a spread that does not grow with distance (:data:`WORLD_SIGMA_M`). A depth
camera, when there is one, is used instead: its error is a few centimetres.

Values (no test set tuned them):

* :data:`WORLD_SIGMA_M`, BlazePose's depth error per joint: on a real-video benchmark with motion-capture
  truth (issue 38's facts: BlazePose heavy's world landmarks, 52 views) the depth sign of a limb segment
  whose ends differ by more than 5 cm is wrong on 21 % of segments. For two joints with independent normal
  depth errors of sigma each, a segment of true depth difference d has the wrong sign with probability
  Phi(-d / (sigma sqrt 2)); 21 % at a typical |d| of 12 cm (an upper arm or thigh at 30-45 degrees to the
  image plane) gives sigma = 12 / (0.81 sqrt 2) = 10.5 cm.
* :data:`WORLD_WEIGHT`, its weight against the 2D landmarks: 1, the maximum-a-posteriori weighting (a world
  depth one sigma off costs what an image landmark one noise sigma off costs), where a depth camera gets 10.
* The person's proportions: the world landmarks' 3D joints give each segment's length on every frame, whatever
  the pose (:func:`world_joints`, learned in fitting.proportions); their scale is not used there either.
* The scale: BlazePose's metres assume an average body; the depths are scaled by the median ratio of the
  model's limb lengths to the world landmarks' own (:func:`world_depths`), so a child or a tall man is
  compared in the model's units.
"""

from __future__ import annotations

import numpy as np

from posed.fitting.body import BodyDimensions
from posed.fitting.kinematics import BODY_LANDMARKS

WORLD_SIGMA_M = 0.105
WORLD_WEIGHT = 1.0
SENSOR_WORLD = np.array([0.0, 0.0, WORLD_SIGMA_M])   # fitting.depth_term's sensor: no surface, no occlusions
WORLD_Z0_M = 10.0   # the world depths are relative; the term's median vote absorbs any offset: any positive one
MIN_SEGMENT_M = 0.05  # a world segment shorter than this gives no scale sample
ROTATION_STEP_DEG = 30.0   # the upper arm's rotation that must show in the world landmarks to be searched: the
                           # sd of the pose prior's left-right tie on it (fitting.problem.PRIOR_SIG)
_ARMS = ((11, 13, 15), (12, 14, 16))   # (shoulder, elbow, wrist), MediaPipe indices: left, right
# the 8 limb segments as MediaPipe landmark indices (upper arm, forearm, thigh, shank; left, right)
_SEGMENTS = ((11, 13), (13, 15), (23, 25), (25, 27), (12, 14), (14, 16), (24, 26), (26, 28))


def _model_lengths(dims: BodyDimensions) -> np.ndarray:
    arm = (dims.upper_arm_m, dims.forearm_m, dims.thigh_m, dims.shank_m)
    return np.array(arm + arm)


def world_scale(world: np.ndarray, dims: BodyDimensions) -> float | None:
    """The model's metres per world-landmark metre: the median over the limb segments both ends of which are
    known of model length / world length; None when no segment is."""
    w = np.asarray(world, dtype=np.float64)[:, :3]
    ratios = []
    for (a, b), model in zip(_SEGMENTS, _model_lengths(dims), strict=True):
        length = float(np.linalg.norm(w[b] - w[a]))
        if np.isfinite(length) and length > MIN_SEGMENT_M:
            ratios.append(model / length)
    return float(np.median(ratios)) if ratios else None


def world_depths(world: np.ndarray | None, dims: BodyDimensions, visibility_drop: float) -> np.ndarray | None:
    """The 12 body landmarks' world depths as the depth term's measurements (metres, :data:`WORLD_Z0_M` plus
    the scaled world z; NaN where the world landmark is unknown or its visibility is below
    ``visibility_drop``, as the image landmarks are dropped), or None without world landmarks."""
    if world is None:
        return None
    w = np.asarray(world, dtype=np.float64)
    if w.shape != (33, 5):
        raise ValueError(f"world landmarks must be a (33, 5) array, got shape {w.shape}")
    scale = world_scale(w, dims)
    if scale is None:
        return None
    rows = w[list(BODY_LANDMARKS)]
    out = WORLD_Z0_M + scale * rows[:, 2]
    out[~np.isfinite(out) | ~(rows[:, 3] >= visibility_drop)] = np.nan
    return out


def world_joints(world: np.ndarray, visibility_drop: float) -> np.ndarray:
    """The 12 body landmarks' world positions (12 x 3, metres, BlazePose's hip-centred axes) for the person's
    lengths (fitting.proportions): NaN rows where the world landmark is unknown or its visibility is below
    ``visibility_drop``, as the image landmarks are dropped."""
    rows = np.asarray(world, dtype=np.float64)[list(BODY_LANDMARKS)]
    out = rows[:, :3].copy()
    out[~np.isfinite(out).all(axis=1) | ~(rows[:, 3] >= visibility_drop)] = np.nan
    return out


def rotation_observable(world: np.ndarray | None, dims: BodyDimensions, visibility_drop: float) -> tuple[bool, bool]:
    """(left, right): whether BlazePose's world landmarks can tell that upper arm's rotation about its own axis.
    Turning the upper arm by ``ROTATION_STEP_DEG`` moves the wrist by ``forearm * sin(elbow flexion) * step``;
    the world landmarks tell it only where that exceeds their depth error ``WORLD_SIGMA_M``: with the model's
    forearm (0.25 m for a 1.70 m body) an elbow flexed between about 54 and 126 degrees. A straighter elbow
    leaves the rotation undefined (a straight arm looks the same however it is turned), and searching it there
    lets the world landmarks' own errors, which are shared along a limb, turn the forearm; a forearm folded
    back on the upper arm moves little too. An arm whose three world landmarks are not all known and visible
    (``visibility_drop``) is not searched either."""
    if world is None:
        return False, False
    w = np.asarray(world, dtype=np.float64)
    need = WORLD_SIGMA_M / (dims.forearm_m * np.radians(ROTATION_STEP_DEG))
    out = []
    for sh, el, wr in _ARMS:
        rows = w[[sh, el, wr]]
        if not (np.isfinite(rows[:, :3]).all() and (rows[:, 3] >= visibility_drop).all()):
            out.append(False)
            continue
        up, fore = rows[1, :3] - rows[0, :3], rows[2, :3] - rows[1, :3]
        n_up, n_fore = float(np.linalg.norm(up)), float(np.linalg.norm(fore))
        if n_up < MIN_SEGMENT_M or n_fore < MIN_SEGMENT_M:
            out.append(False)
            continue
        out.append(float(np.linalg.norm(np.cross(up, fore))) / (n_up * n_fore) > need)
    return out[0], out[1]
