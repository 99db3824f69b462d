"""A landmark whose visibility or presence is outside [0, 1] (interfaces.md section 1: "visibility, presence:
0..1") is invalid input: read as unknown, as a NaN landmark or null is, the frame and its other landmarks
kept; and not silently: the stream counts the values and lines (``stream.invalid``) and reports them when it
ends (an ``InvalidLandmarkValues`` warning, which `posed fit` shows on stderr). Before, such values were kept
as they were and went on to the fit's weights."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from posed.landmarks import iter_recording, read_recording

URFD = "falls/urfd_dev/urfd_00_fall.landmarks.jsonl"
ROOT = Path(__file__).resolve().parents[2]


def _copy(src: Path, dst: Path, edit, n: int = 12) -> Path:
    lines = src.read_text().splitlines()[: n + 1]
    out = [lines[0]]
    for i, line in enumerate(lines[1:]):
        out.append(json.dumps(edit(i, json.loads(line))))
    dst.write_text("\n".join(out) + "\n")
    return dst


# frame index -> [(landmark, column, value)]: visibility (3) and presence (4) outside [0, 1]
BAD = {1: [(25, 3, 1.7)], 4: [(23, 4, -0.2)], 7: [(24, 3, 2.0), (24, 4, 1.5)], 9: [(11, 3, 1.0000001)]}
EDGES = {2: [(12, 3, 0.0), (0, 4, 1.0)]}        # 0 and 1 are in range (landmarks 1-10, 13-22 are null here)


def _edit(bad):
    def edit(i, obj):
        for k, col, v in bad.get(i, []):
            obj["landmarks"][k][col] = v
        return obj
    return edit


def test_out_of_range_visibility_or_presence_is_unknown_and_counted(tmp_path, shared_data):
    src = shared_data / URFD
    _, ref, _ = read_recording(src)
    assert all(ref[i].landmarks is not None for i in range(12)), "the first 12 frames hold a person"
    dst = _copy(src, tmp_path / "prob.landmarks.jsonl", _edit({**BAD, **EDGES}))
    header, stream = iter_recording(dst)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        items = list(stream)
    assert not any(type(x).__name__ == "RecordingProblem" for x in items)
    assert [f.seq for f in items] == [f.seq for f in ref[:12]]          # every frame kept
    for i, (f, r) in enumerate(zip(items, ref[:12], strict=True)):
        lost = {k for k, _, _ in BAD.get(i, [])}
        for k in range(33):
            if k in lost:
                assert np.isnan(f.landmarks[k]).all(), (i, k)              # unknown, as NaN or null is
            elif i in EDGES and k in {kk for kk, _, _ in EDGES[i]}:
                col, v = next((c, v) for kk, c, v in EDGES[i] if kk == k)
                assert f.landmarks[k, col] == v                            # 0 and 1 are probabilities
            else:
                assert np.array_equal(f.landmarks[k], r.landmarks[k], equal_nan=True), (i, k)
    inv = stream.invalid
    assert (inv.values, inv.landmarks, inv.lines) == (5, 4, 4)
    assert inv.first == "line 3: landmark 25 (left_knee) visibility 1.7"    # frame 1 is the file's line 3
    reports = [w for w in caught if w.category.__name__ == "InvalidLandmarkValues"]
    assert len(reports) == 1, [str(w.message) for w in caught]
    text = str(reports[0].message)
    assert text.startswith(f"{dst}: 5 visibility or presence value(s) outside [0, 1] on 4 line(s)")
    assert "first: line 3: landmark 25 (left_knee) visibility 1.7" in text and "read as unknown" in text


def test_world_and_people_landmarks_too(tmp_path, shared_data):
    def edit(i, obj):
        if i == 0:
            lms = obj["landmarks"]
            obj["world"] = [[0.1, 0.2, 0.3, 0.9, 0.9] for _ in range(33)]
            obj["world"][5][4] = 3.0
            other = [None if lm is None else list(lm) for lm in lms]
            other[0][3] = -1.0
            obj["people"] = [{"id": 1, "landmarks": lms}, {"id": 2, "landmarks": other}]
        return obj

    dst = _copy(shared_data / URFD, tmp_path / "world.landmarks.jsonl", edit, n=2)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        _, stream = iter_recording(dst)
        frames = list(stream)
    f = frames[0]
    assert np.isnan(f.world[5]).all() and np.isfinite(f.world[6]).all()
    assert np.isnan(f.people[1].landmarks[0]).all() and np.isfinite(f.people[0].landmarks[0]).all()
    assert (stream.invalid.values, stream.invalid.lines) == (2, 1)
    assert stream.invalid.first == "line 2: world 5 (right_eye) presence 3.0"


def test_a_clean_recording_reports_nothing(shared_data):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, stream = iter_recording(shared_data / URFD)
        n = sum(1 for _ in stream)
    assert n > 0 and not stream.invalid and stream.invalid.values == 0
    assert not [w for w in caught if w.category.__name__ == "InvalidLandmarkValues"]


def test_posed_fit_says_so_on_stderr(tmp_path, shared_data):
    dst = _copy(shared_data / URFD, tmp_path / "prob.landmarks.jsonl", _edit(BAD), n=10)
    r = subprocess.run([sys.executable, "-m", "posed.cli", "fit", str(dst), "-o", str(tmp_path / "fit.jsonl")],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "InvalidLandmarkValues" in r.stderr
    assert "5 visibility or presence value(s) outside [0, 1] on 4 line(s)" in r.stderr
    fits = [json.loads(x) for x in (tmp_path / "fit.jsonl").read_text().splitlines()]
    assert len(fits) == 10


@pytest.mark.parametrize("value", [1.5, -0.5])
def test_landmark_frame_from_json_lists_what_it_left_out(value):
    from posed.landmarks import LandmarkFrame

    row = [10.0, 20.0, 0.0, 0.9, 0.9]
    obj = {"seq": 0, "t": 0.0, "landmarks": [list(row) for _ in range(33)]}
    obj["landmarks"][7][3] = value
    found: list = []
    f = LandmarkFrame.from_json(obj, found)
    assert np.isnan(f.landmarks[7]).all() and np.isfinite(f.landmarks[8]).all()
    assert found == [("landmark 7 (left_ear)", "visibility", value)]
