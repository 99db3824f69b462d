import json

import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.landmarks.recording import (
    LandmarkFrame,
    RecordingError,
    RecordingHeader,
    RecordingProblem,
    iter_recording,
    read_recording,
    write_recording,
)


def _frame(seq, rng, person=True, null_index=None):
    if not person:
        return LandmarkFrame(seq, seq / 30, None)
    lms = rng.uniform(0, 640, (33, 5))
    lms[:, 3:] = rng.uniform(0, 1, (33, 2))
    if null_index is not None:
        lms[null_index] = np.nan
    return LandmarkFrame(seq, seq / 30, lms)


def test_round_trip_exact(tmp_path):
    rng = np.random.default_rng(1)
    header = RecordingHeader((640, 480), 30.0, "test", Intrinsics(600.0, 601.0, 320.0, 240.5, 640, 480),
                             extra={"note": "kept"})
    frames = [_frame(0, rng), _frame(1, rng, person=False), _frame(2, rng, null_index=5)]
    path = tmp_path / "r.landmarks.jsonl"
    assert write_recording(path, header, frames) == 3
    h2, f2, problems = read_recording(path)
    assert problems == []
    assert h2 == header and h2.extra == {"note": "kept"}
    assert f2 == frames
    assert f2[2].landmarks is not None and np.isnan(f2[2].landmarks[5]).all()
    # the file itself follows interfaces.md: null person, null landmark
    lines = path.read_text().splitlines()
    assert json.loads(lines[0])["format"] == "posed.landmarks"
    assert json.loads(lines[2])["landmarks"] is None
    assert json.loads(lines[3])["landmarks"][5] is None


def test_frame_json_round_trip_keeps_unknown_fields():
    obj = {"seq": 3, "t": 0.1, "landmarks": None, "image_size": [640, 480]}
    assert LandmarkFrame.from_json(obj).to_json() == obj


def test_frame_is_immutable():
    f = LandmarkFrame(0, 0.0, np.zeros((33, 5)))
    with pytest.raises(ValueError):
        f.landmarks[0, 0] = 1.0


MALFORMED = [
    ('{"seq": 1, "t": 0.1, "landmarks": [[1,2,3,4,5]]}', "landmarks must be a list of 33 entries"),
    ('{"seq": 1, "t": 0.1}', "'landmarks' is missing"),
    ('{"seq": -1, "t": 0.1, "landmarks": null}', "seq must be a non-negative integer"),
    ('{"seq": 1, "t": NaN, "landmarks": null}', "t must be a finite number"),
    ('{"seq": 1, "t": 0.1, "landmarks": null', "not valid JSON"),
    ('[1, 2]', "must be a JSON object"),
]


@pytest.mark.parametrize("line, message", MALFORMED)
def test_malformed_lines_reported_with_file_and_line(tmp_path, line, message):
    path = tmp_path / "bad.landmarks.jsonl"
    good = json.dumps({"seq": 0, "t": 0.0, "landmarks": None})
    header = json.dumps({"format": "posed.landmarks", "version": 1, "image_size": [640, 480], "fps": 30.0})
    path.write_text("\n".join([header, good, line, good]) + "\n")
    _, frames, problems = read_recording(path)
    assert len(frames) == 2
    assert len(problems) == 1
    assert isinstance(problems[0], RecordingProblem) and problems[0].line == 3
    assert str(problems[0]).startswith(f"{path}:3: ") and message in str(problems[0])


def test_bad_landmark_entry_names_the_landmark(tmp_path):
    lms = [[1.0, 2.0, 0.0, 1.0, 1.0]] * 33
    lms[13] = [1.0, "x", 0.0, 1.0, 1.0]
    header = json.dumps({"format": "posed.landmarks", "version": 1, "image_size": [10, 10], "fps": 5})
    path = tmp_path / "b.landmarks.jsonl"
    path.write_text(header + "\n" + json.dumps({"seq": 0, "t": 0, "landmarks": lms}) + "\n")
    _, frames, problems = read_recording(path)
    assert frames == [] and "landmark 13 (left_elbow)" in str(problems[0])


@pytest.mark.parametrize("content, message", [
    ("", "empty file"),
    ('{"format": "other", "version": 1}', "format is 'other'"),
    ('{"format": "posed.landmarks", "version": 2}', "version 2 is not supported"),
    ('{"format": "posed.landmarks", "version": 1, "image_size": [0, 5], "fps": 30}', "image_size"),
    ("not json", "bad header"),
])
def test_bad_header_raises_with_line_one(tmp_path, content, message):
    path = tmp_path / "h.landmarks.jsonl"
    path.write_text(content)
    with pytest.raises(RecordingError) as err:
        iter_recording(path)
    assert f"{path}:1:" in str(err.value) and message in str(err.value)


def test_missing_file_and_binary_garbage(tmp_path):
    with pytest.raises(RecordingError, match="no such landmark recording"):
        read_recording(tmp_path / "none.jsonl")
    path = tmp_path / "g.landmarks.jsonl"
    header = json.dumps({"format": "posed.landmarks", "version": 1, "image_size": [10, 10], "fps": 5})
    path.write_bytes(header.encode() + b"\n\xff\xfe\x00garbage\n")
    _, frames, problems = read_recording(path)
    assert frames == [] and problems and problems[0].line == 2
