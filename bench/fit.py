"""The fit benchmark (``posed bench fit``): simulated people with ground truth, measured accuracy and speed.

Protocols (docs/bench/fit.md):

* ``paper_poses``: the paper's six poses (section 4.1) x body yaws 20..40 deg x seeds, orthographic camera,
  2D noise 0 and 1 % of body height; image mode.
* ``floor_poses``: lying, sitting-on-the-floor and fallen poses x yaws all round x seeds, same noise levels.
* ``motion``: the motion sequences at 30 fps in video mode (first frame in image mode).
* ``table3``: uDEAS alone over restarts and maximal row lengths, like the paper's Table 3.
* ``ood_mocap`` (:mod:`bench.ood`): out-of-domain: CMU motion capture (a real skeleton, not the model) seen by
  pinhole cameras all around, 5-30 fps, image and video mode, PA-MPJPE / MPJPE / depth flips.

The first four render the fitted humanoid itself ("domain": "in-domain" in every row): a noise-free fit can be
exact there. ``ood_mocap`` rows say "out-of-domain".

Times are the median per-frame CPU time of the fitting thread (``time.thread_time``: one core, robust to
other processes on a shared machine; JIT compilation excluded by a warm-up) and the median wall time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np

from posed.bench import ood as OOD
from posed.bench import simulate as S
from posed.bench.machine import machine as basic_machine
from posed.bench.speed_reference import reference_ms
from posed.fitting import BODY_LANDMARK_NAMES, VARIABLE_NAMES, FitConfig, Fitter, Pose

ANGLES = VARIABLE_NAMES[1:]  # the 18 estimated joint and body angles
HEIGHT_M = 1.60              # the paper's subject: average Korean woman in her twenties
IMAGE_SIZE = (640, 480)
PROTOCOLS = ("paper_poses", "floor_poses", "motion", "table3", OOD.PROTOCOL, "squat_video", "balancing_video")
IN_DOMAIN = "in-domain"
NULL_DIRECTION = {"theta_bd": 1.0, "theta_tr": -1.0, "theta_hp_l": 1.0, "theta_hp_r": 1.0}


@dataclass(frozen=True)
class Row:
    """One benchmark row: an optimizer setting on one protocol and noise level."""

    protocol: str
    optimizer: str           # "udeas", "udeas+lm" (ours), "paper-udeas" (Table 1 bounds, paper loss)
    restarts: int
    max_row: int
    mode: str                # image | video
    noise: float             # 2D noise, fraction of body height


def paper_config(base: FitConfig) -> FitConfig:
    """The paper's method as published: Table 1 bounds, its loss weights and thresholds, uDEAS only."""
    return replace(base, bounds="paper", seed_orientation=False, refine=False, analytic_seeds=False,
                   limb_mirrors=False, com_mode="feet", w_com=0.01, w_sym=0.01, w_sag_tr=0.01, w_cor_tr=0.01,
                   w_tran_tr=0.01, w_sag_sh=0.01, w_cor_sh=0.01, tr_flexion_min_deg=-10.0, tr_lateral_deg=10.0,
                   tr_twist_deg=15.0, sh_flexion_min_deg=-10.0, sh_adduction_max_deg=0.0, pose_prior=0.0,
                   w_cor_hp=0.0)


def row_config(row: Row, base: FitConfig, seed: int) -> FitConfig:
    if row.mode == "video":  # the row names the video settings; image mode (first frame) keeps the base
        cfg = replace(base, seed=seed, video_restarts=row.restarts, video_row_max=row.max_row)
    else:
        cfg = replace(base, seed=seed, restarts=row.restarts, row_max=row.max_row)
    if row.optimizer == "paper-udeas":
        return paper_config(cfg)
    if row.optimizer == "udeas":
        return replace(cfg, refine=False)
    return replace(cfg, refine=True)


def wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def angle_errors(variables: dict, truth: dict) -> np.ndarray:
    return np.array([abs(wrap_deg(variables[k] - truth[k])) for k in ANGLES])


def null_free_error(variables: dict, truth: dict) -> float:
    """Mean angle error after the best shift along the unobservable pelvis-tilt direction."""
    best = math.inf
    for d in np.arange(-180.0, 180.5, 0.5):
        shifted = dict(variables)
        for k, s in NULL_DIRECTION.items():
            shifted[k] = variables[k] + s * d
        best = min(best, float(angle_errors(shifted, truth).mean()))
    return best


def mpjpe3d_mm(joints: dict, truth: dict) -> float:
    d = [np.linalg.norm(np.subtract(joints[k], truth[k])) for k in BODY_LANDMARK_NAMES]
    return float(np.mean(d) * 1000.0)


def machine(speed_ref_before_ms: float | None = None) -> dict:
    """The machine a run was made on, and how fast it ran (bench.speed_reference: before the run when given,
    and now)."""
    import numba

    return {**basic_machine(), "numba": numba.__version__,
            "speed_ref_ms": {"before": speed_ref_before_ms, "after": reference_ms()},
            "note": "2 cores shared with other engineers' jobs: wall times are pessimistic; ms_per_frame is the "
                    "fitting thread's CPU time; speed_ref_ms: a fixed workload's CPU time before and after the run "
                    "(bench.speed_reference: the VM's speed drifts, divide by it to compare runs)"}


class _Acc:
    def __init__(self) -> None:
        self.err: list[float] = []
        self.null_free: list[float] = []
        self.mp3: list[float] = []
        self.e2d: list[float] = []
        self.e2d_px: list[float] = []
        self.loss: list[float] = []
        self.evals: list[int] = []
        self.udeas_ms: list[float] = []
        self.cpu: list[float] = []
        self.wall: list[float] = []
        self.failed = 0
        self.per_case: dict[str, list[float]] = {}

    def add(self, case: str, result, pose: Pose, cpu: float, wall: float, dims, null_free: bool) -> None:
        self.cpu.append(cpu)
        self.wall.append(wall)
        if not result.ok:
            self.failed += 1
            return
        truth = pose.variables()
        e = float(angle_errors(result.variables, truth).mean())
        self.err.append(e)
        self.per_case.setdefault(case, []).append(e)
        if null_free:
            self.null_free.append(null_free_error(result.variables, truth))
        gt = S.ground_truth(pose, dims)
        self.mp3.append(mpjpe3d_mm(result.joints_3d, gt.joints_3d))
        self.e2d.append(result.extra["err2d"])
        self.e2d_px.append(result.extra["err2d_px"])
        self.loss.append(result.loss)
        self.evals.append(result.extra["evals"])
        self.udeas_ms.append(result.extra["udeas_ms"])

    def summary(self, row: Row) -> dict:
        out = {
            "protocol": row.protocol, "domain": IN_DOMAIN, "optimizer": row.optimizer, "restarts": row.restarts, "max_row": row.max_row,
            "mode": row.mode, "noise_px": None, "noise_rel": row.noise,
            "angle_err_deg": _r(np.mean(self.err)) if self.err else None,
            "angle_err_p90_deg": _r(np.percentile(self.err, 90)) if self.err else None,
            "mpjpe3d_mm": _r(np.mean(self.mp3)) if self.mp3 else None,
            "err2d": _r(np.mean(self.e2d), 6) if self.e2d else None,
            "err2d_px": _r(np.mean(self.e2d_px), 3) if self.e2d_px else None,
            "loss": _r(np.mean(self.loss), 6) if self.loss else None,
            "evals": int(np.mean(self.evals)) if self.evals else None,
            "ms_per_frame": _r(np.median(self.cpu) * 1e3, 3) if self.cpu else None,
            "udeas_ms_per_frame": _r(np.median(self.udeas_ms), 3) if self.udeas_ms else None,
            "ms_per_frame_p90": _r(np.percentile(self.cpu, 90) * 1e3, 3) if self.cpu else None,
            "wall_ms_per_frame": _r(np.median(self.wall) * 1e3, 3) if self.wall else None,
            "frames": len(self.cpu), "failed": self.failed,
            "per_case_angle_err_deg": {k: _r(np.mean(v)) for k, v in self.per_case.items()},
        }
        if self.null_free:
            out["angle_err_null_free_deg"] = _r(np.mean(self.null_free))
        return out


def _r(v: float, nd: int = 3) -> float:
    return float(round(float(v), nd))


def _timed_fit(fitter: Fitter, lm, seq, t, mode, intrinsics=None):
    c0, w0 = time.thread_time(), time.perf_counter()
    r = fitter.fit(lm, seq, t, IMAGE_SIZE, mode=mode, intrinsics=intrinsics)
    return r, time.thread_time() - c0, time.perf_counter() - w0


def run_static(row: Row, poses: Iterable[str], yaws: Iterable[float], seeds: Iterable[int], base: FitConfig,
               null_free: bool = False) -> dict:
    """Image-mode fits of static poses; one Fitter per optimizer seed."""
    dims = S.body_dimensions(HEIGHT_M)
    acc = _Acc()
    noise_px = row.noise * S.FILL * IMAGE_SIZE[1]
    for seed in seeds:
        fitter = Fitter(replace(row_config(row, base, seed), body_height_m=HEIGHT_M))
        fitter.warmup()
        for name in poses:
            for yaw in yaws:
                pose = S.pose(name, yaw)
                lm = S.render(pose, dims=dims, image_size=IMAGE_SIZE, noise_px=noise_px,
                              seed=1000 * seed + int(yaw) % 360 + 7 if noise_px > 0 else None)
                r, cpu, wall = _timed_fit(fitter, lm, 0, 0.0, "image")
                acc.add(name, r, pose, cpu, wall, dims, null_free)
    out = acc.summary(row)
    out["noise_px"] = _r(noise_px, 2)
    return out


def run_motion(row: Row, sequences: Iterable[str], yaws: Iterable[float], seeds: Iterable[int],
               base: FitConfig, fps: float = 30.0) -> dict:
    """Video-mode fits of the motion sequences (the first frame of each is fitted in image mode and not timed)."""
    dims = S.body_dimensions(HEIGHT_M)
    acc = _Acc()
    noise_px = row.noise * S.FILL * IMAGE_SIZE[1]
    for seed in seeds:
        fitter = Fitter(replace(row_config(row, base, seed), body_height_m=HEIGHT_M))
        fitter.warmup()
        for name in sequences:
            for yaw in yaws:
                fitter.reset()
                frames = S.render_sequence(S.sequence(name, yaw), fps=fps, dims=dims, image_size=IMAGE_SIZE,
                                           noise_px=noise_px, seed=(1000 * seed + int(yaw) % 360) if noise_px > 0 else None)
                for i, (t, lm, pose) in enumerate(frames):
                    r, cpu, wall = _timed_fit(fitter, lm, i, t, "video")
                    if i == 0:
                        continue
                    acc.add(name, r, pose, cpu, wall, dims, True)
    out = acc.summary(row)
    out["noise_px"] = _r(noise_px, 2)
    return out


@dataclass(frozen=True)
class Plan:
    paper_yaws: tuple[float, ...]
    floor_yaws: tuple[float, ...]
    motion_yaws: tuple[float, ...]
    seeds: tuple[int, ...]
    motion_seeds: tuple[int, ...]
    settings: tuple[tuple[int, int], ...]
    noises: tuple[float, ...]
    table3: bool
    sequences: tuple[str, ...]
    ood: OOD.OodPlan | None = None     # the out-of-domain protocol (None: not run)
    real_video: bool = False           # the real videos: squat (video mode against image mode), balancing (3D truth)


FULL = Plan(paper_yaws=(20.0, 25.0, 30.0, 35.0, 40.0), floor_yaws=(-150.0, -90.0, -30.0, 30.0, 90.0, 150.0),
            motion_yaws=(20.0, 30.0, 40.0, 120.0, -60.0), seeds=(0, 1, 2, 3), motion_seeds=(0,),
            settings=((6, 6), (10, 8), (20, 12)), noises=(0.0, 0.01), table3=True, sequences=S.SEQUENCE_NAMES,
            ood=OOD.FULL_OOD, real_video=True)
QUICK = Plan(paper_yaws=(20.0, 30.0, 40.0), floor_yaws=(-90.0, 30.0, 150.0), motion_yaws=(30.0,),
             seeds=(0,), motion_seeds=(0,), settings=((6, 6),), noises=(0.0, 0.01), table3=False,
             sequences=("stand_to_sit", "fall_forward", "fall_sideways"), ood=OOD.QUICK_OOD,
             real_video=True)


def protocol_description(plan: Plan) -> dict:
    return {
        "domains": {"in-domain": "paper_poses, floor_poses, motion, table3: the fitted humanoid renders itself "
                                 "(orthographic camera, the model's proportions)",
                    "out-of-domain": "ood_mocap: real motion capture, its own skeleton, pinhole cameras"},
        "paper_poses": {"poses": list(S.PAPER_POSES), "yaws_deg": list(plan.paper_yaws), "seeds": len(plan.seeds),
                        "camera": "orthographic, standing body 60% of a 640x480 image", "mode": "image"},
        "floor_poses": {"poses": list(S.FLOOR_POSES), "yaws_deg": list(plan.floor_yaws), "seeds": len(plan.seeds),
                        "camera": "orthographic", "mode": "image"},
        "motion": {"sequences": list(plan.sequences), "yaws_deg": list(plan.motion_yaws), "fps": 30,
                   "seeds": len(plan.motion_seeds), "mode": "video"},
        "noise": "Gaussian 2D noise with sd 0 and 1% of body height (2.88 px), per landmark and axis",
        "body_height_m": HEIGHT_M,
        "angle_err_deg": "mean absolute error over the 18 estimated joint and body angles (eq. 6 without gamma)",
        "mpjpe3d_mm": "mean 3D distance of the 12 joints, pelvis-aligned (both at the mid-hip), camera axes",
        "err2d": "mean 2D reprojection error, fraction of body height (eq. 7)",
        "ms_per_frame": "median CPU time of the fitting thread per frame (one core), JIT excluded",
        "udeas_ms_per_frame": "median CPU time of the uDEAS kernel alone per frame",
    }


def run(plan: Plan = FULL, base: FitConfig | None = None, progress: Callable[[str], None] | None = None,
        protocols: Iterable[str] | None = None) -> dict:
    """The whole benchmark (or only ``protocols``, names of ``PROTOCOLS``); returns ``{"protocol", "machine",
    "results"}``."""
    base = base or FitConfig()
    say = progress or (lambda s: None)
    wanted = set(PROTOCOLS if protocols is None else protocols)
    unknown = wanted - set(PROTOCOLS)
    if unknown:
        raise ValueError(f"unknown protocol(s) {', '.join(sorted(unknown))}; known: {', '.join(PROTOCOLS)}")
    speed_ref_before = reference_ms()
    results = []
    description = protocol_description(plan)
    for noise in plan.noises:
        if "paper_poses" in wanted:
            for restarts, max_row in plan.settings:
                for opt in ("udeas", "udeas+lm"):
                    row = Row("paper_poses", opt, restarts, max_row, "image", noise)
                    say(f"paper_poses {opt} ({restarts},{max_row}) noise {noise}")
                    results.append(run_static(row, S.PAPER_POSES, plan.paper_yaws, plan.seeds, base))
            for restarts, max_row in ((6, 6), (20, 12)):
                row = Row("paper_poses", "paper-udeas", restarts, max_row, "image", noise)
                say(f"paper_poses paper-udeas ({restarts},{max_row}) noise {noise}")
                results.append(run_static(row, S.PAPER_POSES, plan.paper_yaws, plan.seeds, base))
        if "floor_poses" in wanted:
            for opt, (restarts, max_row) in (("udeas", (6, 6)), ("udeas+lm", (6, 6)), ("paper-udeas", (20, 12))):
                row = Row("floor_poses", opt, restarts, max_row, "image", noise)
                say(f"floor_poses {opt} ({restarts},{max_row}) noise {noise}")
                results.append(run_static(row, S.FLOOR_POSES, plan.floor_yaws, plan.seeds, base, null_free=True))
        if "motion" in wanted:
            row = Row("motion", "udeas+lm", base.video_restarts, base.video_row_max, "video", noise)
            say(f"motion video noise {noise}")
            results.append(run_motion(row, plan.sequences, plan.motion_yaws, plan.motion_seeds, base))
    if plan.table3 and "table3" in wanted:
        for restarts, max_row in [(10, m) for m in range(12, 3, -1)] + [(r, 12) for r in range(9, 3, -1)] + [(6, 6)]:
            row = Row("table3", "paper-udeas", restarts, max_row, "image", 0.0)
            say(f"table3 ({restarts},{max_row})")
            results.append(run_static(row, S.PAPER_POSES, plan.paper_yaws, plan.seeds[:1], base))
    if plan.ood is not None and OOD.PROTOCOL in wanted:
        ood = OOD.run(plan.ood, base, progress=say)
        description[OOD.PROTOCOL] = {**ood["description"], "cameras": ood["cameras"], "depth_sim": ood["depth_sim"]}
        results.extend(ood["results"])
    if plan.real_video and "squat_video" in wanted:
        from posed.bench import squat_video
        from posed.daemon.preflight import shared_data
        say("squat_video")
        description["squat_video"] = squat_video.__doc__.split("\n\n")[1].replace("\n", " ")
        results.extend(squat_video.run(shared_data(), replace(base, body_height_m=1.65)))
    if plan.real_video and "balancing_video" in wanted:
        from posed.bench import balancing_video
        from posed.daemon.preflight import shared_data
        say("balancing_video")
        description["balancing_video"] = balancing_video.__doc__.split("\n\n")[1].replace("\n", " ")
        results.extend(balancing_video.run(shared_data(), base))
    return {"protocol": description, "machine": machine(speed_ref_before), "results": results}
