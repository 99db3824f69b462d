"""``posed landmarks`` on a RealSense recording with depth (the .db3 the hal tests make from the real squat
video, a synthetic wall and box for depth): the header's camera and depth, each frame's depth_m as sampled
from hal's aligned depth; without depth the recording is as from any other input."""

from __future__ import annotations

import json

import numpy as np

from posed import hal
from posed.cli import main
from posed.landmarks import read_recording, sample_depth
from tests.hal.conftest import (
    BOX_MM,
    COLOUR_K,
    DB3_FRAMES,
    DEPTH_SCALE,
    SQUAT_FPS,
    WALL_MM,
)


def _hal_frames(path) -> list[hal.Frame]:
    frames = []
    with hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False)) as src:
        while True:
            try:
                frames.append(src.read(5.0))
            except hal.EndOfStream:
                return frames


def test_db3_writes_depth_at_the_landmarks_and_the_header_says_so(models_dir, monkeypatch, squat_db3, tmp_path,
                                                                   capsys):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    out = tmp_path / "squat.landmarks.jsonl"
    assert main(["landmarks", str(squat_db3.path), "-o", str(out)]) == 0
    assert f"{DB3_FRAMES} frame(s), person found in {DB3_FRAMES}" in capsys.readouterr().err
    header, frames, problems = read_recording(out)
    assert problems == []
    assert header.image_size == (COLOUR_K.width, COLOUR_K.height) and header.camera == COLOUR_K
    assert header.fps == SQUAT_FPS
    first_line = json.loads(out.read_text().splitlines()[0])
    assert first_line["depth"] == {"source": "realsense", "aligned_to": "color"}
    assert [f.seq for f in frames] == list(range(DB3_FRAMES))
    assert np.allclose([f.t for f in frames], np.arange(DB3_FRAMES) / SQUAT_FPS, atol=1e-6)

    played = _hal_frames(squat_db3.path)   # the same aligned depth the command read
    assert len(played) == DB3_FRAMES
    seen = set()
    for f, h in zip(frames, played, strict=True):
        assert f.landmarks is not None and f.depth_m is not None
        expected = sample_depth(h.depth, h.depth_scale, f.landmarks)
        assert np.array_equal(f.depth_m, expected, equal_nan=True)
        known = f.depth_m[~np.isnan(f.depth_m)]
        # what the camera sees at the landmarks: the box or the wall behind it (lower median: a measured
        # value, never one in between); the person is only in the colour image
        assert known.size > 20
        assert np.all(np.isclose(known, BOX_MM * DEPTH_SCALE, atol=1e-6)
                      | np.isclose(known, WALL_MM * DEPTH_SCALE, atol=1e-6))
        seen |= set(np.round(known, 3))
    assert seen == {BOX_MM * DEPTH_SCALE, WALL_MM * DEPTH_SCALE}


def test_db3_without_depth_writes_no_depth(models_dir, monkeypatch, squat_db3, tmp_path):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    colour_only = tmp_path / "colour.db3"
    with hal.Db3Writer(colour_only, COLOUR_K, SQUAT_FPS) as w:     # a RealSense recording without depth
        for i, image in enumerate(squat_db3.colour):
            w.write(image, None, 1000.0 + squat_db3.pts_ms[i], i)
    out = tmp_path / "colour.landmarks.jsonl"
    assert main(["landmarks", str(colour_only), "-o", str(out)]) == 0
    assert "depth" not in out.read_text()
    header, frames, problems = read_recording(out)
    assert problems == [] and header.depth is None and header.camera == COLOUR_K
    assert len(frames) == DB3_FRAMES and all(f.depth_m is None and f.landmarks is not None for f in frames)


def test_an_empty_db3_is_an_input_error(models_dir, monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    bad = tmp_path / "broken.db3"
    bad.write_bytes(b"SQLite format 3\x00" + bytes(100))
    assert main(["landmarks", str(bad), "-o", str(tmp_path / "x.landmarks.jsonl")]) == 2
    assert "broken.db3" in capsys.readouterr().err
