"""One frame's fitting problem: landmark weights, the reference scale, the packed ``data`` array of the
kernels, the uDEAS search boxes and the orientation seeds.

Normalized image units: pixels relative to the weighted landmark centroid, divided by
``scale_px = ppm0 * H`` (the reference scale in pixels per metre times the body height), so a 2D error of
0.01 is 1 % of the apparent body height. The variable ``x[0]`` is the size factor relative to ppm0;
the reported gamma is the apparent standing-body height over the image height,
``x[0] * ppm0 * H / image_height``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting import layout as L
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import BODY_LANDMARK_NAMES, BODY_LANDMARKS
from posed.fitting.orientation import MAX_SEEDS, orientation_seeds_into
from posed.fitting.packing import normalized_into, reference_scale_of, weights_into

DEG = math.pi / 180.0

# Search boxes in degrees (gamma relative to the reference scale), eq. (6) order, then the upper arms' rotations
# (psl2, psr2 below: psi_sh_l, psi_sh_r; searched only with world landmarks, else held at 0: :func:`limits`).
#                 gamma  tbd   pbd   sbd   ttr  ptr  str  thl  tkl  thr  tkr   tsl  tel   tsr  ter  phl  phr  psl  psr psl2 psr2
PAPER_LO = np.array([0.7, -10, -10, -90, -20, -40, -30, -20, 0, -20, 0, -180, 0, -180, 0, -40, -40, -40, -40, 0, 0.0])
PAPER_HI = np.array([1.6, 10, 10, 90, 90, 40, 30, 90, 90, 90, 90, 180, 90, 180, 90, 40, 40, 40, 40, 0, 0.0])
WIDE_LO = np.array([0.7, -100, -90, -180, -30, -40, -40, -30, 0, -30, 0, -180, 0, -180, 0, -50, -50, -90, -90, -90,
                    -90.0])
WIDE_HI = np.array([1.6, 100, 90, 180, 90, 40, 40, 130, 160, 130, 160, 180, 160, 180, 160, 40, 40, 40, 40, 70, 70.0])
# Joint limits of the refinement (hard clamps) and of video-mode windows. The upper arms' rotation: external 90,
# internal 70 degrees, the normal range of motion (AAOS; Greene & Heckman 1994).
LIMIT_LO = np.array([0.5, -180, -90, -360, -40, -50, -50, -40, 0, -40, 0, -200, 0, -200, 0, -60, -60, -100, -100, -90,
                     -90.0])
LIMIT_HI = np.array([2.5, 180, 90, 360, 100, 50, 50, 140, 165, 140, 165, 200, 165, 200, 165, 50, 50, 50, 50, 70, 70.0])

# Pose prior of the refinement with noisy landmarks (fitting.fitter._select, docs/body-model.md): rows of
# (x_k - x_partner - mu_k) / sigma_k, degrees; sigma 0 = no row. Left/right symmetry of the limbs and a
# straight spine: it breaks the depth ambiguity of noisy limbs without pulling a pose toward a fixed one.
#                    gamma tbd pbd sbd ttr ptr str thl tkl thr tkr tsl tel tsr ter phl phr psl psr psl2 psr2
PRIOR_MU = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.0])
PRIOR_SIG = np.array([0, 0, 0, 0, 0, 15, 15, 20, 20, 0, 0, 30, 30, 0, 0, 15, 0, 20, 0, 30, 0.0])
PRIOR_PARTNER = np.array([-1, -1, -1, -1, -1, -1, -1, 9, 10, -1, -1, 13, 14, -1, -1, 16, -1, 18, -1, 20, -1.0])

# The model length of each segment of the reference scale (fitting.packing.SCALE_PAIRS, that order)
_SCALE_LENGTHS = ("shoulder", "hip", "upper_arm_m", "upper_arm_m", "thigh_m", "thigh_m", "shank_m", "shank_m")


def to_radians(x_deg: np.ndarray) -> np.ndarray:
    """eq. (6) vector in degrees (gamma unitless) -> kernel units (radians)."""
    x = np.asarray(x_deg, dtype=np.float64) * DEG
    x[..., 0] = np.asarray(x_deg)[..., 0]
    return x


# The limits and the pose prior in kernel units (radians; gamma unitless).
LIMIT_LO_RAD = to_radians(LIMIT_LO)
LIMIT_HI_RAD = to_radians(LIMIT_HI)
PRIOR_MU_RAD = to_radians(PRIOR_MU)
PRIOR_SIG_RAD = to_radians(PRIOR_SIG)
_ROTATIONS = [L.X_PSISH_L, L.X_PSISH_R]
# the same per arm, keyed (left free, right free): a held arm's rotation at 0 (the paper's arm: no world
# landmarks to tell it)
_PER_ARM = {}
for _free in ((False, False), (True, False), (False, True), (True, True)):
    _lo, _hi = LIMIT_LO_RAD.copy(), LIMIT_HI_RAD.copy()
    for _x, _f in zip(_ROTATIONS, _free, strict=True):
        if not _f:
            _lo[_x] = _hi[_x] = 0.0
    _PER_ARM[_free] = (_lo, _hi)
for _a in (LIMIT_LO_RAD, LIMIT_HI_RAD, *(a for pair in _PER_ARM.values() for a in pair)):
    _a.flags.writeable = False

Rotation = bool | tuple[bool, bool]   # the upper arms' rotations free: both (one bool) or (left, right)


def arms(rotation: Rotation) -> tuple[bool, bool]:
    """(left, right) free of ``rotation``."""
    if isinstance(rotation, tuple):
        return bool(rotation[0]), bool(rotation[1])
    return bool(rotation), bool(rotation)


def limits(rotation: Rotation) -> tuple[np.ndarray, np.ndarray]:
    """The joint limits (kernel units, read-only): each upper arm's rotation free within its range where
    ``rotation`` says so (one bool for both arms or a (left, right) pair: world landmarks tell that arm's
    rotation), else held at 0."""
    return _PER_ARM[arms(rotation)]


def to_degrees(x_rad: np.ndarray) -> np.ndarray:
    x = np.asarray(x_rad, dtype=np.float64) / DEG
    x[..., 0] = np.asarray(x_rad)[..., 0]
    return x


def landmark_weights(landmarks: np.ndarray, cfg: FitConfig) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(12 x 2 pixel positions, 12 weights, names of the unusable landmarks) of the body landmarks
    (fitting.packing.weights_into).

    A landmark is unusable when x, y or visibility is not finite or visibility < visibility_drop; weights
    rise linearly from 0.05 at visibility_drop to 1 at visibility_full. An unusable landmark's position is 0.
    """
    xy = np.empty((L.N_LM, 2))
    w = np.empty(L.N_LM)
    lm = np.ascontiguousarray(landmarks, dtype=np.float64)   # one kernel specialization, whatever the caller's
    if lm.shape != (33, 5):
        raise ValueError(f"landmarks must be a (33, 5) array [x_px, y_px, z, visibility, presence], got shape "
                         f"{lm.shape}")
    missing = weights_into(lm, _BODY_IDX, cfg.visibility_drop, max(cfg.visibility_full - cfg.visibility_drop, 1e-6),
                           xy, w)
    return xy, w, ([BODY_LANDMARK_NAMES[i] for i in np.flatnonzero(w == 0.0)] if missing else [])


_BODY_IDX = np.array(BODY_LANDMARKS, dtype=np.int64)


_BODY_CACHE_SIZE = 16
_body_arrays: dict[int, tuple[BodyDimensions, np.ndarray, np.ndarray]] = {}   # id -> (body, as_array, lengths)


def _arrays_of(dims: BodyDimensions) -> tuple[BodyDimensions, np.ndarray, np.ndarray]:
    """(``dims``, ``dims.as_array()``, the model length of each SCALE_PAIRS segment (_SCALE_LENGTHS, metres)),
    read-only, cached by identity for the last few bodies: video mode's learned body is a new object on most
    frames, and hashing one costs more than these arrays. The cache holds the body, so its id is not reused."""
    hit = _body_arrays.get(id(dims))
    if hit is None or hit[0] is not dims:
        if len(_body_arrays) >= _BODY_CACHE_SIZE:
            _body_arrays.clear()
        lengths = {"shoulder": 2 * dims.shoulder_half_m, "hip": 2 * dims.hip_half_m, "upper_arm_m": dims.upper_arm_m,
                   "thigh_m": dims.thigh_m, "shank_m": dims.shank_m}
        seg = np.array([lengths[key] for key in _SCALE_LENGTHS])
        arr = dims.as_array()
        seg.flags.writeable = arr.flags.writeable = False
        hit = _body_arrays[id(dims)] = (dims, arr, seg)
    return hit


def reference_scale(xy: np.ndarray, w: np.ndarray, dims: BodyDimensions) -> float:
    """Pixels per metre: the largest ratio of a projected segment to its length (projection only shortens;
    fitting.packing.reference_scale_of). Returns 0 when no segment is usable.
    """
    return float(reference_scale_of(np.ascontiguousarray(xy, dtype=np.float64),
                                    np.ascontiguousarray(w, dtype=np.float64), _arrays_of(dims)[2], dims.trunk_m))


@dataclass(frozen=True)
class Frame:
    """A packed frame: ``data`` for the kernels and what is needed to map results back to pixels."""

    data: np.ndarray
    ppm0: float            # reference pixels per metre
    scale_px: float        # ppm0 * body height: pixels per normalized unit
    centroid_px: np.ndarray
    weights: np.ndarray
    perspective: bool


_last_constants: tuple = (None, None)   # (cfg, _constants(cfg)) of the last pack: hashing a FitConfig is slow


def _constants_of(cfg: FitConfig) -> np.ndarray:
    """``_constants(cfg)``, the last configuration's without hashing it (a fitter packs every frame with one)."""
    global _last_constants
    last = _last_constants
    if last[0] is not cfg:
        last = _last_constants = (cfg, _constants(cfg))
    return last[1]


@functools.lru_cache(maxsize=16)
def _constants(cfg: FitConfig) -> np.ndarray:
    """The part of the data array that depends on the configuration only (loss weights, thresholds); zero
    elsewhere. Cached per configuration: ``pack`` copies it (read-only here)."""
    data = np.zeros(L.D_SIZE)
    lw = L.D_LW
    data[lw + L.LW_COM] = cfg.w_com
    data[lw + L.LW_SYM] = cfg.w_sym
    data[lw + L.LW_SAG_TR] = cfg.w_sag_tr
    data[lw + L.LW_COR_TR] = cfg.w_cor_tr
    data[lw + L.LW_TRAN_TR] = cfg.w_tran_tr
    data[lw + L.LW_SAG_SH] = cfg.w_sag_sh
    data[lw + L.LW_COR_SH] = cfg.w_cor_sh
    data[lw + L.LW_NULL] = cfg.w_null
    data[lw + L.LW_PRIOR_TR] = cfg.prior_lumbar
    data[lw + L.LW_PRIOR_HP] = cfg.prior_hip
    data[lw + L.LW_PRIOR_UP] = cfg.prior_pelvis_upright
    data[lw + L.LW_COM_MODE] = L.COM_FEET if cfg.com_mode == "feet" else L.COM_SUPPORT
    data[lw + L.LW_CONTACT] = cfg.com_contact
    data[lw + L.LW_MARGIN] = cfg.com_margin
    data[lw + L.LW_SEAT] = 1.0 if cfg.com_mode == "support" else 0.0
    data[lw + L.LW_LIMIT] = cfg.w_limit
    data[lw + L.LW_COR_HP] = cfg.w_cor_hp
    data[L.D_TH:L.D_TH + L.N_TH] = np.array([cfg.tr_flexion_min_deg, cfg.tr_lateral_deg, cfg.tr_twist_deg,
                                             cfg.sh_flexion_min_deg, cfg.sh_adduction_max_deg,
                                             cfg.hp_adduction_max_deg]) * DEG
    data.flags.writeable = False
    return data


def pack(xy: np.ndarray, w: np.ndarray, dims: BodyDimensions, cfg: FitConfig, ppm0: float,
         intrinsics: Intrinsics | None = None,
         fixed_deg: np.ndarray | None = None, rotation: Rotation = False,
         level: np.ndarray | None = None) -> Frame:
    """Build the kernels' data array of one frame (see the D_* layout in fitting.layout); ``rotation``: the
    upper arms' rotations are free (:func:`limits`); ``level``: the frame's D_LEVEL values
    (fitting.vertical.level_data; None: the camera is level)."""
    data = _constants_of(cfg).copy()
    data[L.D_LIM_LO:L.D_LIM_LO + L.N_VAR], data[L.D_LIM_HI:L.D_LIM_HI + L.N_VAR] = limits(rotation)
    scale_px = ppm0 * dims.body_height_m
    c_x, c_y = normalized_into(np.ascontiguousarray(xy, dtype=np.float64), np.ascontiguousarray(w, dtype=np.float64),
                               scale_px, data, L.D_OBS, L.D_W)
    data[L.D_DIMS:L.D_DIMS + L.N_DIMS] = _arrays_of(dims)[1]
    if fixed_deg is not None:
        data[L.D_FIXED:L.D_FIXED + L.N_FIXED] = np.asarray(fixed_deg) * DEG
    perspective = intrinsics is not None
    if perspective:
        fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
        # camera-centred normalized coordinates = data obs + offset
        data[L.D_PROJ:L.D_PROJ + 5] = (1.0, fx / scale_px, fy / scale_px, (c_x - cx) / scale_px, (c_y - cy) / scale_px)
    if level is not None:
        data[L.D_LEVEL:L.D_LEVEL + 10] = level
    return Frame(data, ppm0, scale_px, np.array([c_x, c_y]), w, perspective)


def with_prior(frame: Frame, weight: float, mu, sig, partner) -> np.ndarray:
    """A copy of ``frame``'s data with the refinement's prior rows set: weight lambda, means ``mu``, standard
    deviations ``sig`` (<= 0: no row) and partners ``partner`` (-1: none), each N_VAR values or one for all
    (kernel units; layout D_PRIOR*)."""
    data = frame.data.copy()
    data[L.D_PRIOR] = weight
    data[L.D_PRIOR_MU:L.D_PRIOR_MU + L.N_VAR] = mu
    data[L.D_PRIOR_SIG:L.D_PRIOR_SIG + L.N_VAR] = sig
    data[L.D_PRIOR_PARTNER:L.D_PRIOR_PARTNER + L.N_VAR] = partner
    return data


def image_box(cfg: FitConfig, rotation: Rotation = False) -> tuple[np.ndarray, np.ndarray]:
    """uDEAS search box of image mode (kernel units), within the joint limits (:func:`limits`: the upper arms'
    rotations held at 0 unless ``rotation``; every other bound of the boxes lies within them)."""
    lo, hi = _PAPER_BOX if cfg.bounds == "paper" else _WIDE_BOX
    lim_lo, lim_hi = limits(rotation)
    return np.clip(lo, lim_lo, lim_hi), np.clip(hi, lim_lo, lim_hi)


_PAPER_BOX = (to_radians(PAPER_LO), to_radians(PAPER_HI))
_WIDE_BOX = (to_radians(WIDE_LO), to_radians(WIDE_HI))


def video_box(prev: np.ndarray, cfg: FitConfig, rotation: Rotation = False) -> tuple[np.ndarray, np.ndarray]:
    """+- the window around the previous solution (kernel units), within the joint limits (:func:`limits`):
    knees and elbows never below 0."""
    win = cfg.video_window_deg * DEG
    lo = prev - win
    hi = prev + win
    lo[0] = prev[0] * (1 - cfg.video_window_gamma)
    hi[0] = prev[0] * (1 + cfg.video_window_gamma)
    lim_lo, lim_hi = limits(rotation)
    lo, hi = np.maximum(lo, lim_lo), np.minimum(hi, lim_hi)
    for x, free in zip(_ROTATIONS, arms(rotation), strict=True):
        if not free:   # held at 0 whatever the previous frame had
            lo[x] = hi[x] = 0.0
    return lo, hi


def orientation_seeds(frame: Frame, dims: BodyDimensions, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Starting vectors (kernel units) from the hips and shoulders, assuming a straight lumbar spine
    (fitting.orientation): the hip line gives the pelvis's left axis and mid-hip -> mid-shoulder the torso's
    up axis up to the sign of their depth (orthographic mirror): two seeds (four when the left axis lies in
    the image plane), limbs straight down, gamma 1; none without both hips and both shoulders."""
    out = np.empty((MAX_SEEDS, L.N_VAR))
    n = orientation_seeds_into(frame.data[L.D_OBS:L.D_OBS + 24], frame.weights, dims.body_height_m,
                               dims.hip_half_m, dims.shoulder_half_m, dims.trunk_m, lo, hi,
                               frame.data[L.D_LEVEL:L.D_LEVEL + 10], out)
    return out[:n]


SEED_WINDOW_DEG = 30.0


def restart_boxes(lo: np.ndarray, hi: np.ndarray, seeds: np.ndarray, restarts: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One uDEAS box per restart: a seeded restart searches its body angles within +-30 deg of the seed
    (a hypothesis), the others the whole box."""
    los = np.repeat(lo[None, :], restarts, axis=0)
    his = np.repeat(hi[None, :], restarts, axis=0)
    w = SEED_WINDOW_DEG * DEG
    for r, seed in enumerate(seeds[:restarts]):
        for k in (L.X_TBD, L.X_PBD, L.X_SBD):
            los[r, k] = seed[k] - w
            his[r, k] = seed[k] + w
    return los, his
