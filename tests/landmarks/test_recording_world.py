"""BlazePose's world landmarks in landmark recordings (interfaces.md section 1, a frame's optional ``world``):
they round-trip, a bad entry is named, a recording without them reads and writes as before, and what posed's
own landmark stage writes agrees with BlazePose full's world landmarks of the real squat video as the
tfjs-models project published them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed.cli import main
from posed.landmarks import LANDMARK_NAMES, LandmarkFrame, read_recording, write_recording

SQUAT = ("reference", "tfjs_pose_squats")
# MediaPipe's own tolerance for one world landmark of its pose test image (pose_test_py_expected.json,
# WORLD_DIFF_THRESHOLD): what two runs of BlazePose may differ by and still be "the same" model output.
WORLD_TOLERANCE_M = 0.2


def _world(rng) -> np.ndarray:
    w = rng.normal(0, 0.4, (33, 5))
    w[:, 3:] = rng.uniform(0, 1, (33, 2))
    w[9] = np.nan
    return w


def test_world_round_trips_and_rows_without_a_value_are_null(tmp_path):
    rng = np.random.default_rng(3)
    lms = rng.uniform(0, 480, (33, 5))
    lms[:, 3:] /= 480                     # visibility and presence are probabilities (outside [0, 1]: unknown)
    frames = [LandmarkFrame(0, 0.0, lms, world=_world(rng)), LandmarkFrame(1, 0.1, None)]
    path = tmp_path / "w.landmarks.jsonl"
    from posed.landmarks import RecordingHeader

    write_recording(path, RecordingHeader((640, 480), 10.0, "test"), frames)
    line = json.loads(path.read_text().splitlines()[1])
    assert line["world"][9] is None and len(line["world"]) == 33 and len(line["world"][0]) == 5
    assert "world" not in json.loads(path.read_text().splitlines()[2])       # no person: no world
    _, back, problems = read_recording(path)
    assert problems == [] and back == frames
    assert back[0].world is not None and not back[0].world.flags.writeable
    assert back[0].extra == {}                                               # parsed, not kept as unknown


def test_a_frame_differs_by_its_world():
    rng = np.random.default_rng(4)
    lms = rng.uniform(0, 480, (33, 5))
    w = _world(rng)
    assert LandmarkFrame(0, 0.0, lms, world=w) == LandmarkFrame(0, 0.0, lms, world=w.copy())
    assert LandmarkFrame(0, 0.0, lms, world=w) != LandmarkFrame(0, 0.0, lms)
    w2 = w.copy()
    w2[0, 0] += 0.01
    assert LandmarkFrame(0, 0.0, lms, world=w) != LandmarkFrame(0, 0.0, lms, world=w2)


@pytest.mark.parametrize(("world", "message"), [
    ([[0.1, 0.2, 0.3, 1, 1]] * 32, "world must be a list of 33 entries or null, got 32"),
    ([[0.1, 0.2, 0.3, 1, 1]] * 3 + [[0.1, 0.2, "x", 1, 1]] + [None] * 29,
     f"world 3 ({LANDMARK_NAMES[3]}) must be [x, y, z, visibility, presence] (metres) finite numbers or null"),
    ("far", "world must be a list of 33 entries or null, got str"),
])
def test_a_bad_world_is_named(world, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("]", r"\]")):
        LandmarkFrame.from_json({"seq": 0, "t": 0.0, "landmarks": None, "world": world})


def test_a_partly_unknown_world_row_is_refused():
    w = np.zeros((33, 5))
    w[4, 2] = np.nan
    with pytest.raises(ValueError, match=r"world\[4\] \(right_eye_inner\) must be five finite numbers"):
        LandmarkFrame(0, 0.0, None, world=w)


def test_the_landmark_stage_writes_blazepose_fulls_world_landmarks(shared_data, tmp_path, models_dir, monkeypatch):
    """`posed landmarks` on the real squat video (the daemon's landmark pipeline, video mode) against the world
    landmarks BlazePose full gave on the same 65 frames in tfjs-models (pose_squats_3d.full.json): the same
    model behind a different runtime, ROI tracking and smoothing, so within MediaPipe's own tolerance."""
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    out = tmp_path / "squat.landmarks.jsonl"
    assert main(["landmarks", str(shared_data.joinpath(*SQUAT, "pose_squats.mp4")), "-o", str(out)]) == 0
    _, frames, problems = read_recording(out)
    reference = np.array(json.loads(shared_data.joinpath(*SQUAT, "pose_squats_3d.full.json").read_text()))
    assert problems == [] and len(frames) == len(reference) == 65
    assert all(f.world is not None for f in frames)
    world = np.stack([f.world for f in frames])
    assert np.isfinite(world).all()
    # hip-centred (MediaPipe's world origin is the middle of the hips), metric (a standing adult's
    # shoulder-to-ankle span is about a metre and a half, never centimetres or pixels)
    mid_hip = (world[:, 23, :3] + world[:, 24, :3]) / 2
    assert np.abs(mid_hip).max() < 0.01
    span = np.linalg.norm(world[0, 11, :3] - world[0, 27, :3])
    assert 1.0 < span < 2.0, span
    # visibility and presence are the image landmarks' own
    image = np.stack([f.landmarks for f in frames])
    assert np.allclose(world[:, :, 4], image[:, :, 4])
    err = np.linalg.norm(world[:, :, :3] - reference, axis=2)
    body = [0, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28]
    assert err[:, body].mean(axis=1).max() < WORLD_TOLERANCE_M
    assert (err < WORLD_TOLERANCE_M).mean() >= 0.95
