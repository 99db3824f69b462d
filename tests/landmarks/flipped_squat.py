"""A landmark recording another tool made whose left/right labels flip for a few frames: BlazePose full's own
landmarks and world landmarks of the real squat video (tfjs-models, ``../shared/data/reference/
tfjs_pose_squats``), at 5 fps, the frames named mirrored (image and world landmarks), as BlazePose does
when it reads a front view as a back view. Frames 20-22: the woman stands facing the camera."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from posed.landmarks import LandmarkFrame, RecordingHeader, write_recording
from posed.landmarks.sides import MIRROR

FLIPPED = frozenset({20, 21, 22})
FPS = 5.0


def write(shared_data: Path, path: Path, flip=FLIPPED, extra: dict | None = None) -> Path:
    """The recording at ``path`` with the frames ``flip`` mirrored; ``extra``: header fields."""
    from posed.bench.squat_video import load

    folder = shared_data / "reference" / "tfjs_pose_squats"
    world = [np.column_stack([w, np.ones((33, 2))])
             for w in np.array(json.loads((folder / "pose_squats_3d.full.json").read_text()))]
    frames = [LandmarkFrame(i, i / FPS, lm[MIRROR] if i in flip else lm, world=w[MIRROR] if i in flip else w)
              for i, (lm, w) in enumerate(zip(load(shared_data), world, strict=True))]
    header = RecordingHeader((720, 1280), FPS, "BlazePose full (tfjs-models), pose_squats.mp4", extra=extra or {})
    write_recording(path, header, frames)
    return path
