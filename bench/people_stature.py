"""Stature from one real image (issue 36, "who is who"): the man of pose2sim's balancing video, seen by four
calibrated cameras 1.7-2.1 m high and tilted 18-25 deg down, against his triangulated 3D joints.

Per view: posed's own landmark stage on the video (``posed landmarks``, as the balancing-video benchmark runs it,
cached), the pixels undistorted with the view's calibration; gravity in the camera's axes and its height above
the floor (world z = 0) from the extrinsics, as a measured mount gives them; :func:`falls.stature.stature_m` on
every frame where both of his ankles are within 0.2 m of the floor (he balances on one leg for much of the clip;
the method needs both feet down). Reported: his shoulder height measured from one image (``SHOULDER_OF_STATURE``
times the stature, which is what the metrology measures before the anthropometric ratio) against the
triangulated shoulders' height in the same frames, per view, and the spread between the four views (what
recognising the same person from different places needs).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from posed.bench import balancing_video as bv
from posed.falls.stature import SHOULDER_OF_STATURE, stature_m

FEET_DOWN_M = 0.2


def run(shared: Path, cache: Path | None = None) -> dict:
    folder = shared / bv.DATA
    cache = cache or Path.home() / ".cache" / "posed" / "bench" / "balancing"
    cams = bv.load_cameras(folder)
    truth = bv.load_truth(folder)
    names = list(bv.BODY12)
    shoulders = [names.index("left_shoulder"), names.index("right_shoulder")]
    ankles = [names.index("left_ankle"), names.index("right_ankle")]
    views = []
    for name, cam in cams.items():
        view = bv._load_view(cam, bv.landmark_recording(folder / "balancing" / f"{name}.mp4", cache), truth)
        down = cam.rot @ np.array([0.0, 0.0, -1.0])
        height = float((-cam.rot.T @ cam.t)[2])
        intr = cam.intrinsics(view.image_size)
        est, tru = [], []
        for k, lm in enumerate(view.landmarks):
            if lm is None or truth[k, ankles, 2].max() >= FEET_DOWN_M:
                continue
            h = stature_m(lm, intr, down, height)
            if h is not None:
                est.append(SHOULDER_OF_STATURE * h)
                tru.append(float(truth[k, shoulders, 2].mean()))
        est_a, tru_a = np.array(est), np.array(tru)
        views.append({"view": name, "camera_height_m": round(height, 3),
                      "tilt_deg": round(float(np.degrees(np.arcsin(down[2]))), 1), "frames": len(est),
                      "shoulder_m": round(float(np.median(est_a)), 3) if est else None,
                      "truth_m": round(float(np.median(tru_a)), 3) if est else None,
                      "error_m": round(float(np.median(est_a - tru_a)), 3) if est else None,
                      "stature_m": round(float(np.median(est_a)) / SHOULDER_OF_STATURE, 3) if est else None})
    measured = [v["shoulder_m"] for v in views if v["shoulder_m"] is not None]
    return {"views": views, "spread_between_views_m": round(max(measured) - min(measured), 3) if measured else None,
            "mean_error_m": round(float(np.mean([v["error_m"] for v in views if v["error_m"] is not None])), 3)}
