"""Protocol ``squat_video`` of ``posed bench fit``: video mode against image mode on a real video.

The real squat video of the shared test data (tfjs-models' ``pose_squats.mp4``: one woman, front view,
720x1280, 5 fps, 65 frames) with BlazePose full's own landmarks for every frame (``pose_squats.full.json``).
Image mode fits every frame on its own; video mode fits the sequence at 5 fps (the video's rate) and
replayed at 10 and 30 fps (each frame repeated, as the daemon's paced replay shows it). Per rate: the median
2D error of both modes, the frames where image mode fits better in 2D (any margin, and by more than 5 %)
and the largest knee difference there, and the knees between the squats (frames 20-27 and 43-51, where
image mode gives 3-20 degrees) — the issue's targets: knees within 8 degrees of image mode wherever image
mode fits better, median 2D error no higher than image mode's. Times: the fit's thread CPU time per frame.

Video mode learns the person's proportions (fitting.proportions); image mode fits the configured body. So that
a difference of body is not taken for a lag, ``same_body`` compares video mode with image mode fitted with the
very lengths video mode used at that frame.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from posed.fitting import BodyDimensions, FitConfig, Fitter

VIDEO_FPS = 5.0
RATES = (5.0, 10.0, 30.0)
STANDING = (tuple(range(20, 28)), tuple(range(43, 52)))
REFERENCE = Path("reference") / "tfjs_pose_squats" / "pose_squats.full.json"
IMAGE_SIZE = (720, 1280)


def load(shared_data: Path) -> list[np.ndarray]:
    """The 65 frames' landmarks, (33, 5) with visibility and presence 1."""
    frames = json.loads((shared_data / REFERENCE).read_text())
    return [np.column_stack([np.asarray(p, float), np.ones(33), np.ones(33)]) for p in frames]


def fit_sequence(frames: list[np.ndarray], mode: str, fps: float, base: FitConfig) -> dict:
    """Knee flexion (mean of both, degrees), 2D error (px), CPU ms and the body's lengths of each video frame
    (the first showing of it), replayed at ``fps``."""
    fitter = Fitter(base)
    repeat = round(fps / VIDEO_FPS)
    knee, err, ms, dims = [], [], [], []
    seq = 0
    for i, lm in enumerate(frames):
        for k in range(repeat):
            c0 = time.thread_time()
            r = fitter.fit(lm, seq, i / VIDEO_FPS + k / fps, IMAGE_SIZE, mode=mode)
            dt = (time.thread_time() - c0) * 1e3
            seq += 1
            if k == 0:
                knee.append(0.5 * (r.variables["theta_kn_l"] + r.variables["theta_kn_r"]) if r.ok else np.nan)
                err.append(r.extra["err2d_px"] if r.ok else np.nan)
                ms.append(dt)
                dims.append(fitter.dims)
    return {"knee": np.array(knee), "err": np.array(err), "ms": np.array(ms), "dims": dims}


def image_with(frames: list[np.ndarray], dims: list[BodyDimensions], base: FitConfig) -> dict:
    """Image mode with the given body per frame: knee and 2D error as fit_sequence gives them."""
    knee, err = [], []
    fitters: dict[BodyDimensions, Fitter] = {}
    for i, (lm, d) in enumerate(zip(frames, dims, strict=True)):
        r = fitters.setdefault(d, Fitter(base, dims=d)).fit(lm, i, i / VIDEO_FPS, IMAGE_SIZE, mode="image")
        knee.append(0.5 * (r.variables["theta_kn_l"] + r.variables["theta_kn_r"]) if r.ok else np.nan)
        err.append(r.extra["err2d_px"] if r.ok else np.nan)
    return {"knee": np.array(knee), "err": np.array(err)}


def _agreement(image: dict, video: dict) -> dict:
    """Where image mode fits better in 2D (by any margin, and by more than 5 %): how many frames, the largest
    knee difference there and the frames off by more than 8 degrees."""
    diff = np.abs(video["knee"] - image["knee"])
    better = image["err"] < video["err"]
    clearly = image["err"] < 0.95 * video["err"]
    return {"frames_image_better": int(better.sum()),
            "knee_diff_max_where_image_better_deg": round(float(diff[better].max()), 1) if better.any() else 0.0,
            "frames_over_8deg_where_image_better": [int(i) for i in np.flatnonzero(better & (diff > 8.0))],
            "frames_over_8deg_where_image_clearly_better": [int(i) for i in np.flatnonzero(clearly & (diff > 8.0))]}


def run(shared_data: Path, base: FitConfig | None = None) -> list[dict]:
    """One row per replay rate (see the module docstring)."""
    base = base or FitConfig(body_height_m=1.65)
    frames = load(shared_data)
    fitter_warm = Fitter(base)
    fitter_warm.warmup()
    image = fit_sequence(frames, "image", VIDEO_FPS, base)
    rows = []
    for fps in RATES:
        video = fit_sequence(frames, "video", fps, base)
        same = image_with(frames, video["dims"], base)
        agree = _agreement(image, video)
        rows.append({
            "protocol": "squat_video", "domain": "real video", "fps": fps, "frames": len(frames),
            "median_err2d_px": {"image": round(float(np.median(image["err"])), 2),
                                "video": round(float(np.median(video["err"])), 2)},
            **agree,
            "standing_knee_min_deg": {"image": [round(float(image["knee"][list(w)].min()), 1) for w in STANDING],
                                      "video": [round(float(video["knee"][list(w)].min()), 1) for w in STANDING]},
            "deepest_knee_deg": {"image": round(float(np.nanmax(image["knee"])), 1),
                                 "video": round(float(np.nanmax(video["knee"])), 1)},
            "ms_per_frame_median": {"image": round(float(np.median(image["ms"])), 2),
                                    "video": round(float(np.median(video["ms"])), 2)},
            "same_body": {**_agreement(same, video), "median_err2d_px_image": round(float(np.median(same["err"])), 2)},
            "targets_met": {
                "knees_within_8deg_where_image_better": not agree["frames_over_8deg_where_image_better"],
                "median_err2d_not_above_image": bool(np.median(video["err"]) <= np.median(image["err"])),
            },
        })
    return rows
