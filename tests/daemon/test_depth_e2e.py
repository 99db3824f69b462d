"""Depth through ``posed run``, real processes end to end: a RealSense recording with depth (the .db3 the hal
tests make from the real squat video) -> capture (depth into the shared-memory ring) -> landmark stage (depth
sampled at the landmarks) -> fitting -> the landmarks topic carries ``depth_m``; and a ``*.landmarks.jsonl``
with ``depth_m`` (written by ``posed landmarks`` from the same .db3) passes it on unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from posed import hal
from posed.cli import main
from posed.landmarks import read_recording, sample_depth
from tests.daemon.replay_util import replay_to_end
from tests.hal.conftest import (
    DB3_FRAMES,
)


def _landmark_messages(tmp_path, source, robot: str) -> list[dict]:
    """The daemon on ``source`` to its end: the landmarks topic's messages, by seq."""
    return sorted(replay_to_end(tmp_path, source, robot, ("landmarks",))["landmarks"], key=lambda m: m["seq"])


def _depth(msg: dict) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in msg["depth_m"]], dtype=np.float64)


def _hal_depths(path) -> list[tuple[np.ndarray, float]]:
    out = []
    with hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False)) as src:
        while True:
            try:
                f = src.read(5.0)
            except hal.EndOfStream:
                return out
            out.append((f.depth, f.depth_scale))


@pytest.mark.timeout(300)
def test_db3_depth_reaches_the_landmarks_topic_and_a_recording_passes_it_on(tmp_path, squat_db3, capsys):
    run_dir = tmp_path / "db3"
    run_dir.mkdir()
    msgs = _landmark_messages(run_dir, squat_db3.path, "rgbd")
    assert [m["seq"] for m in msgs] == list(range(DB3_FRAMES))      # lossless replay: every frame
    depths = _hal_depths(squat_db3.path)
    for m, (depth, scale) in zip(msgs, depths, strict=True):
        assert m["landmarks"] is not None and "depth_m" in m
        lms = np.array([[np.nan] * 5 if lm is None else lm for lm in m["landmarks"]], dtype=np.float64)
        # the landmark stage sampled the depth the capture stage put in the ring: exactly hal's
        assert np.array_equal(_depth(m), sample_depth(depth, scale, lms), equal_nan=True)
        assert np.isfinite(_depth(m)).sum() > 20

    # posed landmarks writes the same depth into a recording; replayed, the daemon passes it on unchanged
    recording = tmp_path / "squat.landmarks.jsonl"
    assert main(["landmarks", str(squat_db3.path), "-o", str(recording)]) == 0
    capsys.readouterr()
    _, frames, _ = read_recording(recording)
    assert all(f.depth_m is not None for f in frames)
    run_dir = tmp_path / "jsonl"
    run_dir.mkdir()
    replayed = _landmark_messages(run_dir, recording, "replay")
    assert [m["seq"] for m in replayed] == [f.seq for f in frames]
    for m, f in zip(replayed, frames, strict=True):
        assert np.array_equal(_depth(m), f.depth_m, equal_nan=True)
