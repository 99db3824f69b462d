"""The camera accelerometer's gravity in landmark recordings: a frame's optional ``"gravity"`` round-trips
byte for byte, and a malformed one keeps its line (landmarks and all) with the value left in ``extra``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed.landmarks import LandmarkFrame, RecordingHeader, read_recording, write_recording

HEADER = {"format": "posed.landmarks", "version": 1, "image_size": [640, 480], "fps": 30.0, "source": "rs"}


def _lms() -> list:
    rng = np.random.default_rng(5)
    return [[float(v) for v in row] for row in rng.uniform(0, 1, (33, 5))]


def test_gravity_round_trips_and_equality_sees_it(tmp_path):
    lms = np.array(_lms())
    frames = [LandmarkFrame(0, 0.0, lms, gravity=(0.0, 0.94, 0.34)), LandmarkFrame(1, 0.1, None, gravity=(0, 9.8, 1)),
              LandmarkFrame(2, 0.2, lms)]
    a, b = tmp_path / "a.landmarks.jsonl", tmp_path / "b.landmarks.jsonl"
    write_recording(a, RecordingHeader((640, 480), 30.0, "rs"), frames)
    _, back, problems = read_recording(a)
    assert problems == [] and back == frames
    assert back[0].gravity == (0.0, 0.94, 0.34) and back[1].gravity == (0.0, 9.8, 1.0) and back[2].gravity is None
    assert json.loads(a.read_text().splitlines()[1])["gravity"] == [0.0, 0.94, 0.34]
    write_recording(b, *read_recording(a)[:2])
    assert b.read_bytes() == a.read_bytes()
    assert LandmarkFrame(0, 0.0, lms, gravity=(0.0, 1.0, 0.0)) != LandmarkFrame(0, 0.0, lms, gravity=(0.0, 1.0, 0.1))
    for bad in ((0.0, 0.0, 0.0), (1.0, float("nan"), 0.0), (1.0, 2.0)):
        with pytest.raises(ValueError, match="gravity"):
            LandmarkFrame(0, 0.0, None, gravity=bad)


@pytest.mark.parametrize("bad", [[1.0, 2.0], [0, 0, 0], "down", [1, "x", 2], None])
def test_a_malformed_gravity_keeps_the_frame(tmp_path, bad):
    path = tmp_path / "bad.landmarks.jsonl"
    path.write_text(json.dumps(HEADER) + "\n" + json.dumps({"seq": 0, "t": 0.0, "landmarks": _lms(), "gravity": bad})
                    + "\n")
    _, frames, problems = read_recording(path)
    assert problems == [] and len(frames) == 1 and frames[0].landmarks is not None
    assert frames[0].gravity is None and frames[0].extra == {"gravity": bad}   # counted by the fall watch
    out = tmp_path / "out.landmarks.jsonl"
    write_recording(out, *read_recording(path)[:2])
    assert json.loads(out.read_text().splitlines()[1])["gravity"] == bad        # kept as it was
