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
* The knees' and elbows' flexion (:func:`world_flexion`, :func:`flexion_prior`, :func:`flexion_rows`): the angle
  between a hinge's two segments depends neither on the similarity that relates BlazePose's frame to the
  camera's nor on its scale, so the world landmarks measure it directly, where they were judged usable. Video
  mode takes it as a second measurement of each hinge beside the previous frame's (the temporal prior of
  fitting.fitter): the two normal densities multiplied. Image mode, whose pose prior ties the left hinges to the
  right ones, gets a row per hinge of its own (layout R_FLEX) at the same weight. The world's spread
  :data:`FLEXION_SIGMA_DEG` comes from issue 38's facts (BlazePose heavy's mean absolute error on the real-video
  benchmark: knees 12-13 degrees, elbows 21-30; a normal error's standard deviation is its mean absolute error
  times sqrt(pi / 2): 16 and 32). Its tail is heavy (Cauchy): a world angle ``u`` combined spreads away from the
  previous frame's (in image mode: ``u`` spreads from the best global-search candidate's) has its spread widened
  by sqrt(1 + u^2), so with a tight temporal prior (a high frame rate) a limb BlazePose gets badly wrong barely
  moves the fit's; at 10 fps the prior is wide (50 degrees) and the image landmarks are what overrule it, as for
  any prior. It settles what a near-straight limb's image cannot: a 2D segment a few pixels short reads as a
  30-50 degree bend of that joint.
* The scale: BlazePose's metres assume an average body; the depths are scaled by the median ratio of the
  model's limb lengths to the world landmarks' own (:func:`world_depths`), so a child or a tall man is
  compared in the model's units.
"""

from __future__ import annotations

import math

import numpy as np

from posed.fitting import layout as L
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
# the hinges whose flexion the world landmarks give: (first, middle, last) MediaPipe indices, the variable (layout
# X_*) and its spread; knees from hip-knee-ankle, elbows from shoulder-elbow-wrist
FLEXION_SIGMA_DEG = {"knee": 16.0, "elbow": 32.0}
_HINGES = ((23, 25, 27, L.X_TKN_L, "knee"), (24, 26, 28, L.X_TKN_R, "knee"),
           (11, 13, 15, L.X_TEL_L, "elbow"), (12, 14, 16, L.X_TEL_R, "elbow"))
_HINGE_IDX = np.array([h[:3] for h in _HINGES])
_HINGE_VAR = tuple(h[3] for h in _HINGES)
_HINGE_SIGMA = tuple(math.radians(FLEXION_SIGMA_DEG[h[4]]) for h in _HINGES)
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


def world_flexion(world: np.ndarray, visibility_drop: float) -> list[tuple[int, float, float]]:
    """The knees' and elbows' flexion in BlazePose's world landmarks: (variable index (layout X_*), flexion in
    radians (0 straight), its spread in radians (:data:`FLEXION_SIGMA_DEG`)) for each hinge whose three world
    landmarks are known, visible (``visibility_drop``) and apart (segments longer than MIN_SEGMENT_M)."""
    rows = np.asarray(world, dtype=np.float64)[_HINGE_IDX]            # (4 hinges, 3 landmarks, 5)
    upper, lower = rows[:, 1, :3] - rows[:, 0, :3], rows[:, 2, :3] - rows[:, 1, :3]
    n_up, n_low = np.linalg.norm(upper, axis=1), np.linalg.norm(lower, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (rows[:, :, 3] >= visibility_drop).all(axis=1) & (n_up >= MIN_SEGMENT_M) & (n_low >= MIN_SEGMENT_M)
        cos = np.einsum("ij,ij->i", upper, lower) / (n_up * n_low)
    return [(k, math.acos(min(1.0, max(-1.0, float(c)))), s)
            for k, c, s, good in zip(_HINGE_VAR, cos, _HINGE_SIGMA, ok, strict=True) if good]


def flexion_prior(mu: np.ndarray, sig: np.ndarray, flexion: list[tuple[int, float, float]]) -> None:
    """Fold the world landmarks' hinge ``flexion`` (:func:`world_flexion`) into a prior of independent normal
    rows, in place: each hinge's mean ``mu[k]`` and spread ``sig[k]`` (radians; > 0) become those of the product
    of the two densities, the world's spread first widened by sqrt(1 + u^2) for its distance ``u`` from
    ``mu[k]`` in their combined spread (a Cauchy tail: a world angle far from the prior moves it less than a
    normal measurement would)."""
    for k, angle, s_w in flexion:
        u2 = (angle - mu[k]) ** 2 / (s_w * s_w + sig[k] * sig[k])
        p_prior, p_world = 1.0 / (sig[k] * sig[k]), 1.0 / (s_w * s_w * (1.0 + u2))
        mu[k] = (mu[k] * p_prior + angle * p_world) / (p_prior + p_world)
        sig[k] = 1.0 / math.sqrt(p_prior + p_world)


def flexion_rows(data: np.ndarray, flexion: list[tuple[int, float, float]], weight: float,
                 x_ref: np.ndarray) -> None:
    """Set the refinement's flexion rows (layout R_FLEX, D_FLEX*) of ``data`` in place from the world
    landmarks' hinge ``flexion`` (:func:`world_flexion`): a measurement of each hinge costing ``weight`` (the
    prior rows' lambda) at one spread, the spread widened by sqrt(1 + u^2) for its distance ``u`` (in spreads)
    from ``x_ref`` (the solution being refined: one reweighting step of a Cauchy loss). Image mode's pose
    prior has no row of its own for these hinges (the left ones are ties to the right ones)."""
    for k, angle, s_w in flexion:
        h = L.FLEX_VARS.index(k)
        u = (angle - x_ref[k]) / s_w
        data[L.D_FLEX + h] = angle
        data[L.D_FLEX_W + h] = math.sqrt(weight / (1.0 + u * u)) / s_w


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
