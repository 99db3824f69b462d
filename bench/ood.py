"""The out-of-domain fit benchmark (protocol ``ood_mocap`` of ``posed bench fit``): real 3D motion, a
skeleton that is not the model's, perspective cameras all around, image and video mode.

Every other fit protocol renders the fitted humanoid itself (in-domain: a noise-free fit can be exact). Here
the truth is CMU motion capture (:mod:`bench.mocap_landmarks`: the mocap's own joint centres and proportions,
its hip joints where BlazePose would put its hip landmarks elsewhere), projected by pinhole cameras 2.5-5 m
away at 8 azimuths, at 5/10/15/30 fps, with 2D noise 0 and 1 % of body height (independent per frame, and
correlated in time: ``OodPlan.noise_corr_s``), and with or without a
simulated D435 depth (:mod:`bench.depth_sim`) when the fitter takes one (``Fitter.fit(..., depth_m=)``),
and with three bodies: link lengths from the body height (``height``, the fit without calibration), the
mocap's own lengths as a calibration file (``mocap``, an oracle ``posed calibrate``), and the height body in
video mode for a person seen before (``seen``: the subject's other clip watched first, then a minute without
anybody; :data:`BODIES`).

Metrics per frame against the mocap truth in the camera frame (metres), over the 12 body joints:

* ``mpjpe_mm``: mean joint distance after putting both mid-hips at the origin (the fit's ``joints_3d`` is
  mid-hip-centred, camera axes).
* ``pa_mpjpe_mm``: the same after the best similarity transform (rotation, translation, scale; Procrustes).
* ``depth_flip_rate``: of the 8 limb segments (upper arm, forearm, thigh, shank, both sides), those whose true
  depth difference |z_child - z_parent| exceeds ``FLIP_MIN_DZ_M``, the fraction whose fitted difference has
  the other sign. ``depth_flips_by_true_dz``: the same by bins of the true |dz|, next to how often the
  simulated depth camera itself has the sign wrong there (its measured depth difference of the two
  endpoints has the other sign; ``sensor_unknown_rate``: no depth at an endpoint) — what depth alone can
  tell apart.
* ``angle_err_deg``: mean absolute difference of 8 angles computed from 3D positions the same way for truth
  and fit (:func:`segment_angles`: knee and elbow flexion = angle between the two segments; hip and shoulder
  = angle between the trunk's downward axis and the thigh / upper arm).
* ``root_cam_err_m``: distance from the fit's ``root_cam_m`` (the mid-hip in the camera frame, when the
  fitter reports it) to the true mid-hip; null when the fitter does not report it.
* ``ms_per_frame``: median CPU time of the fitting thread per frame (``time.thread_time``).

Image mode fits the frames of the highest frame rate once (every frame fresh); the lower rates are subsets of
the same frames (5, 10, 15 fps frames are every 6th, 3rd, 2nd 30 fps frame; same noise), so image and video
mode are compared on identical landmarks. Video mode: one Fitter, ``reset()`` before each sequence.
"""

from __future__ import annotations

import inspect
import math
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from posed.bench import mocap_landmarks as M
from posed.bench.depth_sim import DepthSim, simulate_depth
from posed.bench.world_sim import simulate_world
from posed.fitting import BodyDimensions, FitConfig, Fitter, write_calibration
from posed.landmarks import LANDMARK_NAMES

PROTOCOL = "ood_mocap"
DOMAIN = "out-of-domain"
FLIP_MIN_DZ_M = 0.05
# (parent, child) of the 8 limb segments, indices into BODY12
_J = {n: i for i, n in enumerate(M.BODY12)}
SEGMENTS = tuple((_J[f"{s}_{a}"], _J[f"{s}_{b}"]) for s in ("left", "right")
                 for a, b in (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle")))
ANGLE_NAMES = ("knee_l", "knee_r", "elbow_l", "elbow_r", "hip_l", "hip_r", "shoulder_l", "shoulder_r")


# --- metrics -------------------------------------------------------------------------------------------

def procrustes_align(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``pred`` (N, 3) moved by the similarity transform (rotation, uniform scale, translation) that best fits
    ``truth`` in the least-squares sense (Umeyama 1991; a proper rotation, no reflection)."""
    p = np.asarray(pred, float)
    g = np.asarray(truth, float)
    mp, mg = p.mean(0), g.mean(0)
    p0, g0 = p - mp, g - mg
    u, s, vt = np.linalg.svd(p0.T @ g0)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    e = np.diag([1.0, 1.0, d])
    r = u @ e @ vt                     # p0 @ r ~ g0
    var = float((p0 ** 2).sum())
    scale = float((s * np.diag(e)).sum() / var) if var > 0 else 1.0
    return scale * p0 @ r + mg


def mpjpe(pred: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(pred) - np.asarray(truth), axis=1).mean())


def pa_mpjpe(pred: np.ndarray, truth: np.ndarray) -> float:
    return mpjpe(procrustes_align(pred, truth), truth)


FLIP_BINS_M = (FLIP_MIN_DZ_M, 0.08, 0.12, 0.20, math.inf)   # true |dz| bins of depth_flips_by_true_dz


def flip_table(pred: np.ndarray, truth: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """Per true-|dz| bin (``FLIP_BINS_M``) over the 8 limb segments: [counted, fit flipped, sensor wrong sign,
    sensor unknown]; ``measured``: (12,) depth at the body landmarks (m, NaN unknown)."""
    out = np.zeros((len(FLIP_BINS_M) - 1, 4), dtype=np.int64)
    for a, b in SEGMENTS:
        dz_t = truth[b, 2] - truth[a, 2]
        k = int(np.searchsorted(FLIP_BINS_M, abs(dz_t), side="left")) - 1
        if abs(dz_t) <= FLIP_BINS_M[0] or k < 0:
            continue
        dz_m = measured[b] - measured[a]
        out[k] += (1, (pred[b, 2] - pred[a, 2]) * dz_t < 0, np.isfinite(dz_m) and dz_m * dz_t < 0,
                   not np.isfinite(dz_m))
    return out


def depth_flips(pred: np.ndarray, truth: np.ndarray) -> tuple[int, int]:
    """(flipped, counted) over the 8 limb segments: counted = true |dz| > ``FLIP_MIN_DZ_M``; flipped = the
    fitted dz has the other sign (camera frame, z away from the camera): :func:`flip_table` summed."""
    counted, flipped = flip_table(pred, truth, np.full(len(truth), np.nan)).sum(axis=0)[:2]
    return int(flipped), int(counted)


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    c = float(np.dot(u, v) / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-12))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def segment_angles(j: np.ndarray) -> np.ndarray:
    """8 angles (degrees, ``ANGLE_NAMES``) from 12 joints (``BODY12`` order): knee / elbow flexion (0 =
    straight), hip / shoulder: angle between the trunk's downward axis (mid-shoulder -> mid-hip) and the
    thigh / upper arm (0 = hanging along the trunk; includes abduction)."""
    mid_sh = 0.5 * (j[_J["left_shoulder"]] + j[_J["right_shoulder"]])
    mid_hp = 0.5 * (j[_J["left_hip"]] + j[_J["right_hip"]])
    down = mid_hp - mid_sh
    out = []
    for s in ("left", "right"):
        out.append(_angle(j[_J[f"{s}_knee"]] - j[_J[f"{s}_hip"]], j[_J[f"{s}_ankle"]] - j[_J[f"{s}_knee"]]))
    for s in ("left", "right"):
        out.append(_angle(j[_J[f"{s}_elbow"]] - j[_J[f"{s}_shoulder"]], j[_J[f"{s}_wrist"]] - j[_J[f"{s}_elbow"]]))
    for s in ("left", "right"):
        out.append(_angle(down, j[_J[f"{s}_knee"]] - j[_J[f"{s}_hip"]]))
    for s in ("left", "right"):
        out.append(_angle(down, j[_J[f"{s}_elbow"]] - j[_J[f"{s}_shoulder"]]))
    return np.array(out)


def root_cam(result) -> np.ndarray | None:
    """The fit's mid-hip in the camera frame (m), from ``root_cam_m`` (attribute or ``extra`` key), or None."""
    v = getattr(result, "root_cam_m", None)
    if v is None:
        v = result.extra.get("root_cam_m") if isinstance(getattr(result, "extra", None), dict) else None
    if v is None:
        return None
    a = np.asarray(v, float).ravel()
    return a if a.shape == (3,) and np.isfinite(a).all() else None


def fitted_joints(result) -> np.ndarray:
    return np.array([result.joints_3d[n] for n in M.BODY12], dtype=float)


def fitter_takes_depth() -> bool:
    return "depth_m" in inspect.signature(Fitter.fit).parameters


# --- the protocol --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OodPlan:
    clips: tuple[str, ...] = M.CLIPS
    azimuths: tuple[float, ...] = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0)
    fps: tuple[int, ...] = (5, 10, 15, 30)
    noises: tuple[float, ...] = (0.0, 0.01)
    depth: tuple[bool, ...] = (False, True)
    modes: tuple[str, ...] = ("image", "video")
    bodies: tuple[str, ...] = ("height", "mocap", "seen")
    max_s: float | None = None       # use only the first max_s seconds of each clip
    # the noisy levels are also run with 2D noise correlated in time (AR(1) with each of these correlation times,
    # seconds; independent per frame is always run): a landmark extractor's error drifts rather than jumps
    noise_corr_s: tuple[float, ...] = (0.5,)
    # without depth, also with a simulated stream of BlazePose's world landmarks (bench.world_sim) given to the fit
    world: tuple[bool, ...] = (False, True)
    # give the fit each camera's gravity (its rotation in the mocap world, whose z is up), as an IMU would:
    # fitting.vertical (the cameras look 5-8 degrees down: 1.2 m high, aimed 0.8 m high from 3-4 m)
    gravity: bool = False


FULL_OOD = OodPlan()
QUICK_OOD = OodPlan(azimuths=(45.0, 270.0), fps=(10,), noises=(0.0,), depth=(False,), bodies=("height",),
                    world=(False,))
BODIES = {"height": "link lengths from the body height (Drillis-Contini ratios: the fit without calibration)",
          "mocap": "the mocap skeleton's own link lengths and widths, given as a calibration file (what a perfect "
                   "`posed calibrate` would measure): the error left when proportions are known",
          "seen": "the height body, video mode only, for a person seen before: first the subject's other clip from "
                  "90 degrees further round, then a minute without anybody (what video mode learned is kept as "
                  "the prior its new samples start from), then the clip"}
SEEN_TURN_DEG = 90.0   # the "seen" body's earlier visit: the other clip from this much further round


def mocap_dimensions(clip: M.MocapClip) -> BodyDimensions:
    """The clip's own link lengths (first frame, standing) in the model's terms; hand, foot length and ankle
    height keep the height ratios."""
    p = clip.points[0]
    i = {n: k for k, n in enumerate(LANDMARK_NAMES)}

    def dist(a: str, b: str) -> float:
        return float(np.mean([np.linalg.norm(p[i[f"{s}_{a}"]] - p[i[f"{s}_{b}"]]) for s in ("left", "right")]))

    mid_sh = 0.5 * (p[i["left_shoulder"]] + p[i["right_shoulder"]])
    mid_hp = 0.5 * (p[i["left_hip"]] + p[i["right_hip"]])
    return replace(BodyDimensions.from_height(round(clip.height_m, 3)),
                   trunk_m=float(np.linalg.norm(mid_sh - mid_hp)),
                   shoulder_half_m=float(np.linalg.norm(p[i["left_shoulder"]] - p[i["right_shoulder"]])) / 2,
                   hip_half_m=float(np.linalg.norm(p[i["left_hip"]] - p[i["right_hip"]])) / 2,
                   upper_arm_m=dist("shoulder", "elbow"), forearm_m=dist("elbow", "wrist"),
                   thigh_m=dist("hip", "knee"), shank_m=dist("knee", "ankle"))


@dataclass
class Sequence:
    """One clip seen by one camera at the master frame rate: landmarks, depths and truth per frame."""

    clip: str
    camera: M.LookAtCamera
    height_m: float
    times: np.ndarray
    landmarks: list[np.ndarray]          # per noise level: (F, 33, 5)
    depth: np.ndarray                    # (F, 33) simulated depth (m, NaN unknown)
    truth: np.ndarray                    # (F, 12, 3) mid-hip-centred, camera frame
    root: np.ndarray                     # (F, 3) true mid-hip, camera frame
    noise_px: np.ndarray                 # (len(noises),) mean noise sd in px
    world: np.ndarray                    # (F, 33, 5) simulated BlazePose world landmarks (bench.world_sim)


def correlated_noise(rng: np.random.Generator, frames: int, fps: float, corr_s: float) -> np.ndarray:
    """Unit-variance Gaussian noise for the 33 landmarks' x and y over ``frames`` frames at ``fps``, each
    coordinate an AR(1) process whose correlation falls by 1/e in ``corr_s`` seconds (F x 33 x 2); started
    from its stationary distribution."""
    a = math.exp(-1.0 / (fps * corr_s))
    out = np.empty((frames, 33, 2))
    e = rng.normal(0.0, 1.0, (33, 2))
    for t in range(frames):
        if t:
            e = a * e + math.sqrt(1.0 - a * a) * rng.normal(0.0, 1.0, (33, 2))
        out[t] = e
    return out


def build_sequence(clip: M.MocapClip, azimuth: float, master_fps: int, noises: Iterable[float],
                   seed: int, max_s: float | None = None, sim: DepthSim | None = None,
                   noise_corr_s: float = 0.0) -> Sequence:
    """``noises``: 2D noise levels (fractions of the body height, in pixels at the mid-hip's depth), each a
    landmark set; independent per frame, or with ``noise_corr_s`` > 0 correlated in time (:func:`correlated_noise`,
    the same standard deviation). The truth and the depth do not depend on the noise."""
    cam = M.choose_distance(clip, azimuth)
    k = cam.intrinsics
    times, pts = clip.resample(master_fps, max_s)
    pc = cam.to_camera(pts)                                  # (F, 33, 3)
    mid = 0.5 * (pc[:, 23] + pc[:, 24])
    truth = pc[:, M.BODY12_IDX] - mid[:, None, :]
    lms, npx = [], []
    for i, noise in enumerate(noises):
        rng = np.random.default_rng([seed, i] if noise_corr_s <= 0 else [seed, i, 7])
        sd = noise * clip.height_m * k.fy / mid[:, 2]       # 1 % of body height in pixels at the mid-hip's depth
        if noise_corr_s > 0 and noise > 0:
            e = correlated_noise(rng, len(pc), master_fps, noise_corr_s)
            lms.append(np.array([M.project(p, k, offset_px=s * e_t) for p, s, e_t in zip(pc, sd, e, strict=True)]))
        else:
            lms.append(np.array([M.project(p, k, float(s), rng) for p, s in zip(pc, sd, strict=True)]))
        npx.append(float(sd.mean()))
    drng = np.random.default_rng([seed, 99])
    depth = np.array([simulate_depth(p, k, drng, sim) for p in pc])
    world = simulate_world(truth, master_fps, np.random.default_rng([seed, 77]))
    return Sequence(clip.name, cam, clip.height_m, times, lms, depth, truth, mid, np.array(npx), world)


class _Acc:
    def __init__(self) -> None:
        self.pa: list[float] = []
        self.mp: list[float] = []
        self.flip_bins = np.zeros((len(FLIP_BINS_M) - 1, 4), dtype=np.int64)
        self.ang: list[np.ndarray] = []
        self.root: list[float] = []
        self.root_missing = 0
        self.cpu: list[float] = []
        self.wall: list[float] = []
        self.failed = 0
        self.frames = 0
        self.e2d_px: list[float] = []
        self.loss: list[float] = []
        self.evals: list[int] = []
        self.per_clip: dict[str, list[float]] = {}
        self.per_az: dict[float, list[float]] = {}

    def add(self, seq: Sequence, i: int, result, cpu: float, wall: float) -> None:
        self.frames += 1
        self.cpu.append(cpu)
        self.wall.append(wall)
        if not result.ok:
            self.failed += 1
            return
        pred = fitted_joints(result)
        truth = seq.truth[i]
        pa = pa_mpjpe(pred, truth)
        self.pa.append(pa)
        self.mp.append(mpjpe(pred, truth))
        self.flip_bins += flip_table(pred, truth, seq.depth[i][M.BODY12_IDX])
        self.ang.append(np.abs(segment_angles(pred) - segment_angles(truth)))
        rc = root_cam(result)
        if rc is None:
            self.root_missing += 1
        else:
            self.root.append(float(np.linalg.norm(rc - seq.root[i])))
        self.e2d_px.append(float(result.extra.get("err2d_px", math.nan)))
        self.loss.append(float(result.loss))
        self.evals.append(int(result.extra.get("evals", 0)))
        self.per_clip.setdefault(seq.clip, []).append(pa)
        self.per_az.setdefault(seq.camera.azimuth_deg, []).append(pa)

    def summary(self) -> dict:
        ang = np.array(self.ang) if self.ang else np.zeros((0, 8))
        counted, flipped = (int(v) for v in self.flip_bins.sum(axis=0)[:2])
        return {
            "frames": self.frames, "failed": self.failed,
            "pa_mpjpe_mm": _r(np.mean(self.pa) * 1e3, 1) if self.pa else None,
            "pa_mpjpe_p90_mm": _r(np.percentile(self.pa, 90) * 1e3, 1) if self.pa else None,
            "mpjpe_mm": _r(np.mean(self.mp) * 1e3, 1) if self.mp else None,
            "depth_flip_rate": _r(flipped / counted, 4) if counted else None,
            "depth_flip_segments": counted,
            "depth_flips_by_true_dz": [
                {"true_dz_m": f"{lo:g}-{hi:g}", "segments": int(n),
                 "fit_flip_rate": _r(fl / n, 4) if n else None,
                 "sensor_wrong_sign_rate": _r(wr / n, 4) if n else None,
                 "sensor_unknown_rate": _r(un / n, 4) if n else None}
                for (lo, hi), (n, fl, wr, un) in zip(zip(FLIP_BINS_M[:-1], FLIP_BINS_M[1:], strict=True), self.flip_bins,
                                                     strict=True)],
            "angle_err_deg": _r(ang.mean(), 2) if len(ang) else None,
            "angle_err_by_angle_deg": {n: _r(v, 2) for n, v in zip(ANGLE_NAMES, ang.mean(0), strict=True)}
            if len(ang) else {},
            "root_cam_err_m": _r(np.mean(self.root), 4) if self.root else None,
            "root_cam_reported": self.root_missing == 0 and bool(self.root),
            "err2d_px": _r(np.nanmean(self.e2d_px), 3) if self.e2d_px else None,
            "loss": _r(np.mean(self.loss), 6) if self.loss else None,
            "evals": int(np.mean(self.evals)) if self.evals else None,
            "ms_per_frame": _r(np.median(self.cpu) * 1e3, 3) if self.cpu else None,
            "ms_per_frame_p90": _r(np.percentile(self.cpu, 90) * 1e3, 3) if self.cpu else None,
            "wall_ms_per_frame": _r(np.median(self.wall) * 1e3, 3) if self.wall else None,
            "per_clip_pa_mpjpe_mm": {k: _r(np.mean(v) * 1e3, 1) for k, v in self.per_clip.items()},
            "per_azimuth_pa_mpjpe_mm": {str(int(k)): _r(np.mean(v) * 1e3, 1) for k, v in sorted(self.per_az.items())},
        }


def _r(v: float, nd: int = 3) -> float:
    return float(round(float(v), nd))


def _fit(fitter: Fitter, lm, i: int, t: float, mode: str, k, depth: np.ndarray | None,
         world: np.ndarray | None = None, gravity: np.ndarray | None = None):
    kw = {"depth_m": depth} if depth is not None else {}
    if world is not None:
        kw["world"] = world
    if gravity is not None:
        kw["gravity"] = gravity
    c0, w0 = time.thread_time(), time.perf_counter()
    r = fitter.fit(lm, i, t, k.size, mode=mode, intrinsics=k, **kw)
    return r, time.thread_time() - c0, time.perf_counter() - w0


def _visit(fitter: Fitter, visit: Sequence, ni: int, step: int, use_depth: bool, gravity: bool = False) -> float:
    """Video mode over ``visit`` (its landmarks of noise level ``ni``, every ``step``-th frame), as an earlier
    sighting of the person: what it learns stays; returns the time of its last frame (s)."""
    k = visit.camera.intrinsics
    down = visit.camera.rot @ np.array([0.0, 0.0, -1.0]) if gravity else None
    for i in range(0, len(visit.times), step):
        _fit(fitter, visit.landmarks[ni][i], i, float(visit.times[i]), "video", k,
             visit.depth[i] if use_depth else None, None, down)
    fitter.reset()
    return float(visit.times[-1])


def run(plan: OodPlan = FULL_OOD, base: FitConfig | None = None, data_dir: Path | None = None,
        progress: Callable[[str], None] | None = None, seed: int = 13) -> dict:
    """The protocol; returns ``{"description", "cameras", "results"}`` (one result row per mode, fps, noise,
    noise correlation time, body and depth, over all clips and azimuths)."""
    base = base or FitConfig()
    say = progress or (lambda s: None)
    if data_dir is None:
        from posed.daemon.preflight import shared_data
        data_dir = shared_data() / "mocap" / "cmu"
    takes_depth = fitter_takes_depth()
    master = math.lcm(*plan.fps)
    steps = {f: master // f for f in plan.fps}
    if any(master % f for f in plan.fps):
        raise ValueError(f"frame rates {plan.fps} must divide their least common multiple")
    accs: dict[tuple, _Acc] = {}
    cameras = []
    depth_err: list[float] = []
    depth_nan = depth_n = 0
    noise_px: dict[float, list[float]] = {}
    tmp = tempfile.TemporaryDirectory(prefix="posed-ood-")
    clips = {name: M.load_clip(Path(data_dir) / f"{name}.bvh") for name in plan.clips}
    for ci, name in enumerate(plan.clips):
        clip = clips[name]
        fitters = {}
        for body in plan.bodies:
            cfg = replace(base, body_height_m=round(clip.height_m, 3), calibration="")
            if body == "mocap":
                path = str(Path(tmp.name) / f"{name}.yaml")
                write_calibration(path, mocap_dimensions(clip), frames=1, source=f"CMU {name} (bench.ood)")
                cfg = replace(cfg, calibration=path)
            elif body not in ("height", "seen"):
                raise ValueError(f"body {body!r} is not one of: {', '.join(BODIES)}")
            fitters[body] = Fitter(cfg)
            fitters[body].warmup()
        for ai, az in enumerate(plan.azimuths):
            seq = build_sequence(clip, az, master, plan.noises, seed=1000 * ci + ai + seed, max_s=plan.max_s)
            cam = seq.camera
            cameras.append({"clip": name, "azimuth_deg": az, "distance_m": cam.distance_m,
                            "tilt_deg": _r(cam.tilt_deg, 1), "camera_height_m": M.CAMERA_HEIGHT_M,
                            "mid_hip_depth_m": [_r(seq.root[:, 2].min(), 2), _r(seq.root[:, 2].max(), 2)],
                            "frames_at_master_fps": len(seq.times)})
            body_d = seq.depth[:, M.BODY12_IDX]
            true_z = seq.truth[:, :, 2] + seq.root[:, None, 2]
            ok = np.isfinite(body_d)
            depth_n += body_d.size
            depth_nan += int((~ok).sum())
            depth_err.extend(np.abs(body_d[ok] - true_z[ok]).tolist())
            noisy = tuple(n for n in plan.noises if n > 0)
            variants = [(noise, 0.0, seq.landmarks[ni]) for ni, noise in enumerate(plan.noises)]
            for corr in (c for c in plan.noise_corr_s if c > 0 and noisy):
                drifting = build_sequence(clip, az, master, noisy, seed=1000 * ci + ai + seed, max_s=plan.max_s,
                                          noise_corr_s=corr)   # the same truth and depth
                variants += [(noise, corr, drifting.landmarks[ni]) for ni, noise in enumerate(noisy)]
            for ni, noise in enumerate(plan.noises):
                noise_px.setdefault(noise, []).append(float(seq.noise_px[ni]))
            # the "seen" body's earlier visit: the subject's other clip (this one if alone), turned
            if "seen" in plan.bodies and "video" in plan.modes:
                other = plan.clips[(ci + 1) % len(plan.clips)]
                visit = build_sequence(clips[other], (az + SEEN_TURN_DEG) % 360.0, master, plan.noises,
                                       seed=1000 * ci + ai + seed + 500, max_s=plan.max_s)
            down = cam.rot @ np.array([0.0, 0.0, -1.0]) if plan.gravity else None
            for noise, corr, lms in variants:
                for body, fitter in fitters.items():
                    for use_depth, use_world in [(d, w) for d in plan.depth for w in plan.world if not (d and w)]:
                        fit_depth = use_depth and takes_depth
                        if use_depth and not takes_depth:
                            continue   # the rows without depth stand in (flagged), see below
                        wl = seq.world if use_world else [None] * len(lms)
                        for mode in plan.modes:
                            if body == "seen" and mode != "video":
                                continue   # image mode learns nothing: the height body's rows
                            say(f"ood {name} az {az:g} noise {noise} (correlated {corr:g} s) body {body} "
                                f"depth {use_depth} world {use_world} {mode}")
                            if mode == "image":
                                wanted = sorted(set().union(*(range(0, len(lms), s) for s in steps.values())))
                                res = {}
                                for i in wanted:
                                    fitter.reset()
                                    res[i] = _fit(fitter, lms[i], i, float(seq.times[i]), "image",
                                                  cam.intrinsics, seq.depth[i] if fit_depth else None, wl[i],
                                                  down)
                                for f, s in steps.items():
                                    acc = accs.setdefault(("image", f, noise, corr, body, use_depth, use_world),
                                                          _Acc())
                                    for i in range(0, len(lms), s):
                                        acc.add(seq, i, *res[i])
                            else:
                                for f, s in steps.items():
                                    acc = accs.setdefault(("video", f, noise, corr, body, use_depth, use_world),
                                                          _Acc())
                                    fitter.reset()
                                    fitter.forget_body()   # each sequence is a new video of a new person ...
                                    t0 = 0.0
                                    if body == "seen":     # ... or of one seen before, a minute ago
                                        t0 = _visit(fitter, visit, plan.noises.index(noise), s, fit_depth, plan.gravity)
                                        t0 += base.proportions_forget_s + 30.0
                                    for i in range(0, len(lms), s):
                                        acc.add(seq, i, *_fit(fitter, lms[i], i, t0 + float(seq.times[i]), "video",
                                                              cam.intrinsics, seq.depth[i] if fit_depth else None,
                                                              wl[i], down))
    tmp.cleanup()
    results = []
    for (mode, f, noise, corr, body, use_depth, use_world), acc in accs.items():
        row = {"protocol": PROTOCOL, "domain": DOMAIN, "optimizer": "udeas+lm", "body": body,
               "restarts": base.restarts if mode == "image" else base.video_restarts,
               "max_row": base.row_max if mode == "image" else base.video_row_max, "mode": mode, "fps": f,
               "noise_rel": noise, "noise_corr_s": corr, "noise_px": _r(np.mean(noise_px[noise]), 2),
               "depth": use_depth, "depth_used": bool(use_depth and takes_depth), "world": use_world}
        row.update(acc.summary())
        row["mpjpe3d_mm"] = row["mpjpe_mm"]   # the name the in-domain rows use
        results.append(row)
    if True in plan.depth and not takes_depth:
        for row in [r for r in results if not r["depth"]]:
            results.append({**row, "depth": True, "depth_used": False,
                            "note": "Fitter.fit takes no depth_m: the same fits as without depth"})
    order = {b: k for k, b in enumerate(plan.bodies)}
    results.sort(key=lambda r: (r["depth"], r["world"], order[r["body"]], r["noise_rel"], r["noise_corr_s"], r["fps"],
                                r["mode"]))
    return {
        "description": description(plan, takes_depth),
        "cameras": cameras,
        "depth_sim": {"body_landmarks": depth_n, "nan_rate": _r(depth_nan / max(depth_n, 1), 4),
                      "median_abs_err_m": _r(np.median(depth_err), 4) if depth_err else None,
                      "note": "measured depth vs the true joint-centre depth at the 12 body landmarks "
                              "(includes the surface offsets and background hits)"},
        "noise_px": {f"{n:g}": _r(np.mean(v), 2) for n, v in noise_px.items()},
        "results": results,
    }


def description(plan: OodPlan, takes_depth: bool) -> dict:
    sim = DepthSim()
    return {
        "domain": DOMAIN,
        "clips": list(plan.clips), "azimuths_deg": list(plan.azimuths), "fps": list(plan.fps),
        "noise": [f"{n:g} x body height (px at the mid-hip depth)" for n in plan.noises],
        "noise_corr_s": [0.0, *(c for c in plan.noise_corr_s if c > 0)],
        "noise_correlation": "0: independent per frame; > 0: each landmark coordinate's noise an AR(1) process whose "
                             "correlation falls by 1/e in that many seconds (same standard deviation), for the "
                             "noisy levels (bench.ood.correlated_noise): a landmark extractor's error drifts",
        "depth": list(plan.depth), "fitter_takes_depth": takes_depth, "modes": list(plan.modes),
        "bodies": {b: BODIES[b] for b in plan.bodies},
        "truth": "CMU mocap joint centres (bench.bvh.cmu_landmark_world), not the fitted model: the mocap's own "
                 "hip joints (0.137 m apart) and proportions; body height from the standing nose height / 0.93",
        "camera": f"pinhole {M.IMAGE_SIZE[0]}x{M.IMAGE_SIZE[1]}, fx = fy = {M.FOCAL_PX:g} px, "
                  f"{M.CAMERA_HEIGHT_M} m high aiming at {M.AIM_HEIGHT_M} m above the middle of the path, "
                  "distance (horizontal, to the middle of the path) the nearest of 2.5..5 m by 0.25 that keeps "
                  "every landmark of the clip in the image",
        "azimuth": "0 = camera in front of the walking direction, 90 = on the walker's left",
        "depth_sim": {"sigma_m": f"{sim.sigma_k:.4f} * z^2", "hole_rate": sim.hole_rate,
                      "background_rate": sim.background_rate,
                      "background_behind_m": list(sim.background_behind_m),
                      "surface_offset_m": "torso 0.10, limbs 0.04, hands/feet 0.02, face 0",
                      "self_occlusion": sim.self_occlusion and "a landmark's pixel ray that first enters another "
                                        "part of the body (capsules: torso 0.10 m, head 0.08, limb segments 0.04 "
                                        "radius) measures that part's surface (bench.depth_sim.CAPSULES)"},
        "mpjpe_mm": "mean over the 12 body joints, both mid-hips at the origin, camera frame",
        "pa_mpjpe_mm": "the same after a per-frame similarity (Procrustes with scale)",
        "depth_flip_rate": f"fraction of limb segments (true |dz| > {FLIP_MIN_DZ_M} m) whose fitted dz has the "
                           "other sign",
        "angle_err_deg": "mean |difference| of knee, elbow flexion and hip, shoulder angles to the trunk axis, "
                         "computed from 3D positions for truth and fit alike",
        "root_cam_err_m": "|fit root_cam_m - true mid-hip| (camera frame); null when the fit reports none",
        "ms_per_frame": "median CPU time of the fitting thread per frame (time.thread_time), JIT excluded",
        "image_mode_frames": "image mode fits the highest rate's frames; lower rates are subsets of them",
    }
