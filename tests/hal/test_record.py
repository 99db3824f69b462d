"""``posed record`` and hal.record: what a source saw comes back through the replay source, timestamps and
seqs included (video + sidecar, image folder, RealSense .db3 with depth)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed import hal
from posed.cli import main
from posed.hal.sidecar import read_sidecar, sidecar_path
from tests.hal.conftest import DB3_FRAMES, SQUAT_FPS


def replay(path, query="realtime=false"):
    with hal.open_source(f"file:{path}?{query}") as src:
        frames = []
        while True:
            try:
                frames.append(src.read(2.0))
            except hal.EndOfStream:
                return frames, src.info


def test_video_with_drops_round_trips_seq_and_time(tmp_path, squat_video, squat_frames):
    out = tmp_path / "field.mkv"
    with hal.open_source(f"file:{squat_video}?realtime=false&drop=0.25&seed=4") as src:
        summary = hal.record(src, str(out), max_frames=20)
    assert summary.frames == 20 and summary.format == "video" and summary.reason == "frames"
    assert summary.sidecar == str(sidecar_path(out)) == str(tmp_path / "field.timestamps.jsonl")
    side = read_sidecar(summary.sidecar)
    recorded_seqs = [side.by_frame[i][0] for i in range(20)]
    assert recorded_seqs != list(range(20))  # the drops left gaps
    frames, info = replay(out)
    assert info["timestamps"] == "sidecar" and info["codec"].upper() == "FFV1"
    assert [f.seq for f in frames] == recorded_seqs
    assert all(np.array_equal(f.image, squat_frames[f.seq]) for f in frames)  # FFV1 is lossless
    t = np.array([f.t - frames[0].t for f in frames])
    assert np.allclose(t, (np.array(recorded_seqs) - recorded_seqs[0]) / SQUAT_FPS, atol=1e-5)


def test_cli_records_for_n_seconds_in_real_time(tmp_path, squat_video, capsys):
    out = tmp_path / "clip.avi"
    code = main(["record", "--source", f"file:{squat_video}", "-o", str(out), "--seconds", "1.5"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["format"] == "video" and summary["reason"] == "time"
    # Frames are due 0.2 s apart from the first read, which is after the recording's clock starts, and a read
    # never returns a frame due after the end: at most the 8 due at 0, 0.2, ..., 1.4 s (all 65 when replay is
    # not paced). At least the 3 due by 0.4 s, which leaves 1.1 s of slack for a loaded machine.
    assert 3 <= summary["frames"] <= 8
    frames, _ = replay(out)
    assert [f.seq for f in frames] == list(range(summary["frames"]))


def test_image_folder_output_replays_its_sidecar(tmp_path, squat_video, squat_frames):
    out = tmp_path / "shots"
    code = main(["record", "--source", f"file:{squat_video}?realtime=false&corrupt_at=1", "-o", str(out),
                 "--frames", "4"])
    assert code == 0
    assert sorted(p.name for p in out.iterdir())[:2] == ["frame_000000.png", "frame_000001.png"]
    frames, info = replay(out)
    assert [f.seq for f in frames] == [0, 2, 3, 4]  # the corrupt frame was skipped and stays missing
    assert all(np.array_equal(f.image, squat_frames[f.seq]) for f in frames)
    assert np.allclose([f.t - frames[0].t for f in frames], [0.0, 0.4, 0.6, 0.8], atol=1e-6)


def test_db3_keeps_depth_intrinsics_and_timestamps(tmp_path, squat_db3):
    first, _ = replay(squat_db3.path)
    out = tmp_path / "again.db3"
    with hal.open_source(f"file:{squat_db3.path}?realtime=false") as src:
        summary = hal.record(src, str(out))
    assert summary.format == "db3" and summary.has_depth and summary.frames == DB3_FRAMES
    assert summary.reason == "end of stream"
    second, info = replay(out)
    assert info["depth_alignment"] == "raw"  # already on the colour grid: no second alignment
    assert [f.seq for f in second] == [f.seq for f in first]
    for a, b in zip(first, second, strict=True):
        assert np.array_equal(a.image, b.image) and np.array_equal(a.depth, b.depth)
        assert a.intrinsics == b.intrinsics and a.depth_scale == pytest.approx(b.depth_scale)
    assert np.allclose(np.diff([f.t for f in second]), np.diff([f.t for f in first]), atol=1e-6)


def test_db3_needs_intrinsics(tmp_path, squat_video):
    with hal.open_source(f"file:{squat_video}?realtime=false") as src:
        with pytest.raises(hal.SourceUnsupported, match="needs the camera intrinsics.*source.fx"):
            hal.record(src, str(tmp_path / "x.db3"), max_frames=2)


def test_sidecar_damage(tmp_path, squat_video):
    out = tmp_path / "v.mkv"
    with hal.open_source(f"file:{squat_video}?realtime=false") as src:
        hal.record(src, str(out), max_frames=3)
    side = sidecar_path(out)
    lines = side.read_text().splitlines()
    side.write_text("\n".join(lines[:-1] + [lines[-1][:7]]) + "\n")  # the recorder was killed mid-line
    assert sorted(read_sidecar(side).by_frame) == [0, 1]
    side.write_text("\n".join([lines[0], "{oops", lines[2], lines[3]]) + "\n")
    with pytest.raises(hal.SourceCorrupt, match=r"v.timestamps.jsonl:2: bad frame line"):
        replay(out)


def test_cli_errors(tmp_path, capsys):
    assert main(["record", "--source", f"file:{tmp_path / 'nope.mp4'}", "-o", str(tmp_path / "o.mkv")]) == 66
    assert "nope.mp4: no such file" in capsys.readouterr().err
    assert main(["record", "--source", "file:x.mp4", "-o", str(tmp_path / "o.gif")]) == 64
    assert "cannot record to '.gif'" in capsys.readouterr().err
