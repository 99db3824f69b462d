"""Property-based fuzzing of the landmark recording reader (``*.landmarks.jsonl``, interfaces.md section 1):
whatever a file holds, reading never raises on a frame line (each non-blank line is a frame or a problem
naming its line), a header it cannot read is a ``RecordingError``, and what it reads is well formed."""

from __future__ import annotations

import json
import math

import numpy as np
from hypothesis import example, given
from hypothesis import strategies as st

from posed.landmarks import (
    LandmarkFrame,
    RecordingError,
    RecordingHeader,
    RecordingProblem,
    read_recording,
    write_recording,
)
from tests.fuzz.strategies import FUZZ, deep_nesting, json_line, json_values

HEADER = {"format": "posed.landmarks", "version": 1, "image_size": [640, 480], "fps": 30.0, "source": "fuzz"}

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
landmark = st.one_of(st.none(), st.lists(finite, min_size=5, max_size=5))
valid_frame = st.fixed_dictionaries({
    "seq": st.integers(min_value=0, max_value=2**40),
    "t": st.floats(min_value=0, max_value=1e6, allow_nan=False),
    "landmarks": st.one_of(st.none(), st.lists(landmark, min_size=33, max_size=33)),
})


def _mutate(frame: dict, key: str, value) -> dict:
    out = dict(frame)
    if key == "<drop>":
        out.pop("seq", None)
    else:
        out[key] = value
    return out


mutated_frame = st.builds(_mutate, valid_frame,
                          st.sampled_from(["seq", "t", "landmarks", "depth_m", "<drop>", "extra"]), json_values)
# a landmark list whose one entry is replaced by anything
mutated_landmark = st.builds(lambda f, i, v: {**f, "landmarks": [v if j == i else lm for j, lm in enumerate(
    f["landmarks"] or [None] * 33)]}, valid_frame, st.integers(0, 32), json_values)
frame_line = st.one_of(
    valid_frame.map(json_line), mutated_frame.map(json_line), mutated_landmark.map(json_line),
    json_values.map(json_line), st.text(max_size=200),
    st.integers(min_value=50, max_value=100_000).map(deep_nesting),
)


def _write(tmp_path, header: bytes, lines: list[bytes]):
    p = tmp_path / "fuzz.landmarks.jsonl"
    p.write_bytes(header + b"\n" + b"\n".join(x.replace(b"\n", b" ").replace(b"\r", b" ") for x in lines) + b"\n")
    return p


def _check_frame(f: LandmarkFrame) -> None:
    assert isinstance(f.seq, int) and f.seq >= 0 and math.isfinite(f.t)
    if f.landmarks is not None:
        assert f.landmarks.shape == (33, 5)
        rows_ok = np.isfinite(f.landmarks).all(axis=1) | np.isnan(f.landmarks).all(axis=1)
        assert rows_ok.all(), "a landmark row must be all finite or all unknown (NaN)"
    if f.depth_m is not None:
        d = f.depth_m
        assert d.shape == (33,) and (np.isnan(d) | (d > 0)).all()


@FUZZ
@given(lines=st.lists(st.one_of(frame_line.map(lambda s: s.encode("utf-8", "surrogatepass")),
                                st.binary(max_size=100)), max_size=12))
@example(lines=[b"\x1f"])             # found by the fuzzer: str.strip() took the unit separator for a blank
def test_any_frame_lines_give_frames_or_problems(tmp_path_factory, lines):
    path = _write(tmp_path_factory.mktemp("rec"), json.dumps(HEADER).encode(), lines)
    header, frames, problems = read_recording(path)
    assert header.image_size == (640, 480)
    nonblank = [x for x in path.read_bytes().split(b"\n")[1:] if x.strip(b" \t\r\n")]   # JSON's whitespace
    # a line that is not UTF-8 is a problem even when it is blank after decoding errors
    assert len(frames) + len(problems) == len(nonblank)
    for f in frames:
        _check_frame(f)
    for p in problems:
        assert isinstance(p, RecordingProblem) and p.line >= 2 and p.message and str(path) in str(p)


@FUZZ
@given(first=st.one_of(
    st.binary(max_size=200),
    st.builds(lambda k, v: json.dumps({**HEADER, k: v}, allow_nan=True).encode(),
              st.sampled_from(["format", "version", "image_size", "fps", "source", "camera", "depth"]), json_values),
    st.builds(lambda cam: json.dumps({**HEADER, "camera": cam}, allow_nan=True).encode(),
              st.dictionaries(st.sampled_from(["fx", "fy", "cx", "cy", "width"]),
                              st.one_of(st.floats(), st.integers(), st.none()), max_size=5)),
    st.integers(min_value=50, max_value=100_000).map(lambda n: deep_nesting(n).encode()),
))
def test_any_header_is_read_or_refused_with_a_recording_error(tmp_path_factory, first):
    path = _write(tmp_path_factory.mktemp("hdr"), first.replace(b"\n", b" ").replace(b"\r", b" "), [])
    try:
        header, frames, problems = read_recording(path)
    except RecordingError as exc:
        assert str(path) in str(exc)
        return
    assert isinstance(header, RecordingHeader) and header.fps > 0 and math.isfinite(header.fps)
    assert all(v > 0 for v in header.image_size)


@FUZZ
@given(frames=st.lists(valid_frame, max_size=8))
def test_valid_frames_round_trip(tmp_path_factory, frames):
    path = tmp_path_factory.mktemp("rt") / "rt.landmarks.jsonl"
    parsed = [LandmarkFrame.from_json(f) for f in frames]
    write_recording(path, RecordingHeader.from_json(HEADER), parsed)
    _, back, problems = read_recording(path)
    assert problems == [] and back == parsed
