"""``posed run`` on a recording another tool made (real processes, a Zenoh router on 127.0.0.1): where its
extractor flipped the person's left and right, the capture stage's replay puts them back before the fit, as
``posed fit`` and ``posed falls`` do (landmarks.RecordingSides), so the landmarks and pose topics carry the
person's own left."""

from __future__ import annotations

import numpy as np
import pytest

from posed.landmarks import read_recording
from tests.daemon.replay_util import replay_to_end
from tests.landmarks import flipped_squat


def _landmarks(msg: dict) -> np.ndarray:
    return np.array([[np.nan] * 5 if lm is None else lm for lm in msg["landmarks"]], dtype=np.float64)


@pytest.mark.timeout(300)
def test_the_replay_puts_back_left_and_right_a_recording_flipped(tmp_path, shared_data):
    clean = flipped_squat.write(shared_data, tmp_path / "clean.landmarks.jsonl", flip=())
    flipped = flipped_squat.write(shared_data, tmp_path / "flipped.landmarks.jsonl")
    _, truth, _ = read_recording(clean)
    got = replay_to_end(tmp_path, flipped, "sides", ("landmarks", "pose"))
    landmarks = sorted(got["landmarks"], key=lambda m: m["seq"])
    assert [m["seq"] for m in landmarks] == [f.seq for f in truth]           # lossless replay: every frame
    for m, f in zip(landmarks, truth, strict=True):
        np.testing.assert_allclose(_landmarks(m), f.landmarks, atol=1e-3, err_msg=f"seq {m['seq']}")
    poses = {m["seq"]: m for m in got["pose"]}
    # she faces the camera: her left shoulder is on the image's right (+x), in the frame before the flipped
    # ones as in them
    for seq in (min(flipped_squat.FLIPPED) - 1, *sorted(flipped_squat.FLIPPED)):
        joints = poses[seq]["joints_3d"]
        assert joints["left_shoulder"][0] > joints["right_shoulder"][0], seq
