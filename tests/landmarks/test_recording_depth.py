"""Depth in landmark recordings (interfaces.md section 1): a frame's optional ``depth_m`` and the header's
``depth``. Recordings without them read and write byte for byte as before; with them they round-trip too."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.landmarks import (
    DepthSource,
    LandmarkFrame,
    RecordingError,
    RecordingHeader,
    read_recording,
    write_recording,
)

HEADER_LINE = ('{"format": "posed.landmarks", "version": 1, "image_size": [640, 480], "fps": 30.0, '
               '"source": "cam", "camera": {"fx": 600.0, "fy": 600.0, "cx": 320.0, "cy": 240.0}}')


def _landmarks(rng) -> np.ndarray:
    lms = rng.uniform(0, 480, (33, 5))
    lms[:, 3:] = rng.uniform(0, 1, (33, 2))
    lms[7] = np.nan
    return lms


def _depth(rng) -> np.ndarray:
    d = rng.uniform(0.4, 6.0, 33)
    d[[2, 7, 30]] = np.nan
    return d


def _rewrite(src, dst):
    header, frames, problems = read_recording(src)
    assert problems == []
    write_recording(dst, header, frames)
    return header, frames


def test_a_recording_without_depth_reads_and_writes_byte_for_byte(tmp_path):
    rng = np.random.default_rng(3)
    header = RecordingHeader((640, 480), 30.0, "cam", Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480),
                             extra={"note": "kept"})
    frames = [LandmarkFrame(0, 0.0, _landmarks(rng)), LandmarkFrame(1, 1 / 30, None),
              LandmarkFrame(2, 2 / 30, _landmarks(rng), extra={"tag": 1})]
    a, b = tmp_path / "a.landmarks.jsonl", tmp_path / "b.landmarks.jsonl"
    write_recording(a, header, frames)
    h2, f2 = _rewrite(a, b)
    assert b.read_bytes() == a.read_bytes()
    assert h2.depth is None and all(f.depth_m is None for f in f2)
    assert "depth" not in a.read_text()
    # a file written by hand in the format's own words, too
    hand = tmp_path / "hand.landmarks.jsonl"
    lms = [None if np.isnan(r).any() else [float(v) for v in r] for r in _landmarks(rng)]
    hand.write_text("\n".join([HEADER_LINE, json.dumps({"seq": 0, "t": 0.0, "landmarks": lms}),
                               json.dumps({"seq": 1, "t": 0.033, "landmarks": None})]) + "\n")
    _rewrite(hand, b)
    assert b.read_bytes() == hand.read_bytes()


def test_depth_round_trips_and_the_file_says_it_as_interfaces_md(tmp_path):
    rng = np.random.default_rng(4)
    header = RecordingHeader((640, 480), 30.0, "realsense", depth=DepthSource())
    frames = [LandmarkFrame(0, 0.0, _landmarks(rng), depth_m=_depth(rng)), LandmarkFrame(1, 1 / 30, None),
              LandmarkFrame(2, 2 / 30, _landmarks(rng)),                     # a person, no depth this frame
              LandmarkFrame(3, 3 / 30, _landmarks(rng), depth_m=np.full(33, np.nan))]
    a, b = tmp_path / "a.landmarks.jsonl", tmp_path / "b.landmarks.jsonl"
    write_recording(a, header, frames)
    h2, f2 = _rewrite(a, b)
    assert b.read_bytes() == a.read_bytes()
    assert h2 == header and h2.depth == DepthSource("realsense", "color")
    assert f2 == frames
    assert np.array_equal(f2[0].depth_m, frames[0].depth_m, equal_nan=True) and f2[0].depth_m.dtype == np.float64
    assert f2[1].depth_m is None and f2[2].depth_m is None
    lines = [json.loads(x) for x in a.read_text().splitlines()]
    assert lines[0]["depth"] == {"source": "realsense", "aligned_to": "color"}
    depth = lines[1]["depth_m"]
    assert len(depth) == 33 and depth[2] is None and depth[7] is None and depth[30] is None
    assert depth[0] == frames[0].depth_m[0]
    assert "depth_m" not in lines[2] and "depth_m" not in lines[3]
    assert lines[4]["depth_m"] == [None] * 33


def test_frames_differing_only_in_depth_are_not_equal():
    lms = np.zeros((33, 5))
    assert LandmarkFrame(0, 0.0, lms) != LandmarkFrame(0, 0.0, lms, depth_m=np.ones(33))
    assert LandmarkFrame(0, 0.0, lms, depth_m=np.ones(33)) != LandmarkFrame(0, 0.0, lms, depth_m=2 * np.ones(33))
    assert LandmarkFrame(0, 0.0, lms, depth_m=np.ones(33)) == LandmarkFrame(0, 0.0, lms, depth_m=np.ones(33))


def test_depth_is_read_only_and_checked():
    f = LandmarkFrame(0, 0.0, None, depth_m=np.ones(33))
    with pytest.raises(ValueError):
        f.depth_m[0] = 2.0
    with pytest.raises(ValueError, match=r"depth_m must have shape \(33,\)"):
        LandmarkFrame(0, 0.0, None, depth_m=np.ones(32))
    with pytest.raises(ValueError, match=r"depth_m\[4\] \(right_eye_inner\) is -1.0"):
        LandmarkFrame(0, 0.0, None, depth_m=np.r_[np.ones(4), -1.0, np.ones(28)])


def test_unknown_fields_of_the_depth_object_and_a_null_depth_m_are_kept():
    header = json.loads(HEADER_LINE)
    header["depth"] = {"source": "realsense", "aligned_to": "color", "model": "D435"}
    assert RecordingHeader.from_json(header).to_json() == header
    frame = {"seq": 0, "t": 0.0, "landmarks": None, "depth_m": None}
    parsed = LandmarkFrame.from_json(frame)
    assert parsed.depth_m is None and parsed.to_json() == frame


@pytest.mark.parametrize("depth_m, message", [
    ([1.0] * 32, "depth_m must be a list of 33 depths"),
    ("far", "depth_m must be a list of 33 depths"),
    ([1.0] * 12 + [-0.5] + [1.0] * 20, "depth_m 12 (right_shoulder) must be a positive number"),
    ([1.0] * 11 + ["x"] + [1.0] * 21, "depth_m 11 (left_shoulder) must be a positive number"),
])
def test_a_bad_depth_m_is_a_problem_naming_the_line_and_landmark(tmp_path, depth_m, message):
    path = tmp_path / "bad.landmarks.jsonl"
    good = json.dumps({"seq": 0, "t": 0.0, "landmarks": None, "depth_m": [1.5] * 33})
    path.write_text("\n".join([HEADER_LINE, good, json.dumps({"seq": 1, "t": 0.1, "landmarks": None,
                                                               "depth_m": depth_m})]) + "\n")
    _, frames, problems = read_recording(path)
    assert len(frames) == 1 and frames[0].depth_m.tolist() == [1.5] * 33
    assert len(problems) == 1 and problems[0].line == 3 and message in str(problems[0])


@pytest.mark.parametrize("depth, message", [
    ("realsense", "depth must be an object"),
    ({"source": "realsense"}, "depth.aligned_to must be a string"),
    ({"source": 3, "aligned_to": "color"}, "depth.source must be a string"),
])
def test_a_bad_depth_header_is_a_recording_error(tmp_path, depth, message):
    header = json.loads(HEADER_LINE)
    header["depth"] = depth
    path = tmp_path / "h.landmarks.jsonl"
    path.write_text(json.dumps(header) + "\n")
    with pytest.raises(RecordingError, match=message):
        read_recording(path)
