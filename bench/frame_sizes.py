"""The working size, chosen by measurement (issue 39): BlazePose (the daemon's landmark stage, tracking on) on
real clips at their full size and scaled down by whole factors 2, 3 and 4 as the capture stage scales them,
the landmarks taken back to the full size's pixels; how well they agree with the full size's, and what each
size costs (the downscale, the landmark stage, the bytes through the ring).

Agreement per frame: the median, over the 12 body landmarks (shoulders, elbows, wrists, hips, knees, ankles)
that the full size found, of the distance between the two, divided by the person's height in the image (the
full size's body landmarks' vertical extent); then the median and the 90th percentile over the frames where
both found a person. ``detect_agree``: the fraction of frames where both found a person or both found none.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from posed import hal

BODY = [11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28]
CLIPS = ("multi_person/s2d_enter.mp4", "multi_person/bend_hand.mp4", "pose2sim_demo/balancing/cam01.mp4",
         "pose2sim_demo/balancing/cam03.mp4", "tfjs_pose_squats/pose_squats.mp4")
FACTORS = (1, 2, 3, 4)


def read_frames(path, n: int, size: tuple[int, int] | None = None) -> list[np.ndarray]:
    """The first ``n`` frames of a video (resized to ``size`` = (width, height) with cubic interpolation when
    given: a clip brought to a camera's size)."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    out = []
    while len(out) < n:
        ok, im = cap.read()
        if not ok:
            break
        out.append(np.ascontiguousarray(cv2.resize(im, size, interpolation=cv2.INTER_CUBIC) if size else im))
    cap.release()
    return out


def _landmarks(frames: list[np.ndarray], k: int, config) -> tuple[list, list[float], list[float]]:
    from posed.landmarks import PoseLandmarker

    lm = PoseLandmarker(config)
    lm.warmup()
    out, scale_ms, land_ms = [], [], []
    for i, im in enumerate(frames):
        t0 = time.perf_counter()
        small = hal.downscale(im, k)
        t1 = time.perf_counter()
        f = lm.process(small, i / 30.0, i)
        t2 = time.perf_counter()
        scale_ms.append((t1 - t0) * 1e3)
        land_ms.append((t2 - t1) * 1e3)
        pts = None if f.landmarks is None else f.landmarks[:, :2] * k
        out.append(pts)
    return out, scale_ms, land_ms


def measure(shared, frames_per_clip: int = 60, factors=FACTORS) -> list[dict]:
    """One row per clip and factor."""
    from posed.daemon.config import Config

    config = Config().landmarks
    rows = []
    for clip in CLIPS:
        frames = read_frames(shared / "reference" / clip, frames_per_clip)
        h, w = frames[0].shape[:2]
        ref = None
        for k in factors:
            got, scale_ms, land_ms = _landmarks(frames, k, config)
            if k == 1:
                ref = got
            errs, agree = [], 0
            for a, b in zip(ref, got, strict=True):
                agree += (a is None) == (b is None)
                if a is None or b is None:
                    continue
                ok = np.isfinite(a[BODY]).all(axis=1) & np.isfinite(b[BODY]).all(axis=1)
                if ok.sum() < 3:
                    continue
                height = float(np.ptp(a[BODY][ok, 1]))
                if height <= 0:
                    continue
                errs.append(float(np.median(np.linalg.norm(a[BODY][ok] - b[BODY][ok], axis=1))) / height)
            rows.append({
                "clip": clip, "size": f"{w}x{h}", "factor": k, "working": f"{w // k}x{h // k}",
                "frames": len(frames), "person_frames": sum(g is not None for g in got),
                "detect_agree": round(agree / len(frames), 3),
                "err_median_pct": round(100 * float(np.median(errs)), 2) if errs else None,
                "err_p90_pct": round(100 * float(np.percentile(errs, 90)), 2) if errs else None,
                "downscale_ms": round(float(np.median(scale_ms)), 2),
                "landmarks_ms": round(float(np.median(land_ms)), 1),
                "ring_MB_per_frame": round((w // k) * (h // k) * 3 / 1e6, 2),
            })
    return rows
