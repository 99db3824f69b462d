"""A synthetic scene judged on its true joints by a fresh detector with numbered event ids, and a hook that gives
it what a frame's sensors would (the robot's pose, a depth floor) before each frame."""

from __future__ import annotations

import itertools
from collections.abc import Callable

from posed.bench.falls_scenarios import frames, truth_result
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector


def judge_scene(sc, before_frame: Callable[[FallDetector, object], None] | None = None,
                cfg: FallsConfig | None = None) -> tuple[FallDetector, list]:
    """The detector after the scene and every message it sent; ``before_frame(det, camera)`` runs before each
    frame's update."""
    counter = itertools.count()
    det = FallDetector(cfg or FallsConfig(), "r1", fit_frame="camera", id_factory=lambda: f"ev{next(counter)}")
    cam = sc.camera
    out = []
    for fr in frames(sc):
        if before_frame is not None:
            before_frame(det, cam)
        out += det.update(truth_result(fr, cam), fr.landmarks, (cam.width, cam.height), cam.intrinsics)
    return det, out
