"""A landmark with a NaN or infinite value is unknown, as null is: the frame and its other landmarks are kept
(before, the whole frame was skipped as a bad line). A header line with a UTF-8 byte-order mark is read."""

from __future__ import annotations

import json

import numpy as np

from posed.landmarks import RecordingProblem, iter_recording, read_recording

URFD = "falls/urfd_dev/urfd_00_fall.landmarks.jsonl"


def _copy(src, dst, edit, n: int = 12) -> None:
    lines = src.read_text().splitlines()[: n + 1]
    out = [lines[0]]
    for i, line in enumerate(lines[1:]):
        obj = json.loads(line)
        out.append(edit(i, obj))
    dst.write_text("\n".join(out) + "\n")


def test_a_nan_or_infinite_landmark_is_unknown_and_the_frame_kept(tmp_path, shared_data):
    src = shared_data / URFD
    dst = tmp_path / "nan.landmarks.jsonl"

    def edit(i, obj):
        if obj.get("landmarks") is not None:
            if i % 3 == 0:
                obj["landmarks"][23][0] = float("nan")        # json.dumps writes NaN
            elif i % 3 == 1:
                obj["landmarks"][25][3] = float("inf")        # ... and Infinity
        return json.dumps(obj)

    _copy(src, dst, edit)
    _, ref, _ = read_recording(src)
    _, frames, problems = read_recording(dst)
    assert problems == [], [str(p) for p in problems]
    assert [f.seq for f in frames] == [f.seq for f in ref[: len(frames)]] and len(frames) == 12
    with_person = [(i, f, r) for i, (f, r) in enumerate(zip(frames, ref, strict=False)) if r.landmarks is not None]
    assert with_person, "the recording's first frames hold a person"
    for i, f, r in with_person:
        lost = {0: 23, 1: 25}.get(i % 3)
        for k in range(33):
            if k == lost:
                assert np.isnan(f.landmarks[k]).all(), (i, k)
            else:
                assert np.array_equal(f.landmarks[k], r.landmarks[k], equal_nan=True), (i, k)


def test_a_landmark_with_a_string_is_still_a_bad_line(tmp_path, shared_data):
    dst = tmp_path / "bad.landmarks.jsonl"

    def edit(i, obj):
        if i == 2 and obj.get("landmarks") is not None:
            obj["landmarks"][23][0] = "12.5"
        return json.dumps(obj)

    _copy(shared_data / URFD, dst, edit, n=4)
    _, stream = iter_recording(dst)
    items = list(stream)
    bad = [x for x in items if isinstance(x, RecordingProblem)]
    assert len(bad) == 1 and bad[0].line == 4 and "landmark 23 (left_hip)" in bad[0].message, bad


def test_a_header_with_a_byte_order_mark_is_read(tmp_path, shared_data):
    src = shared_data / URFD
    dst = tmp_path / "bom.landmarks.jsonl"
    dst.write_bytes(b"\xef\xbb\xbf" + src.read_bytes())
    h1, f1, p1 = read_recording(src)
    h2, f2, p2 = read_recording(dst)
    assert p2 == p1 and h2.image_size == h1.image_size and len(f2) == len(f1) > 0
