"""``posed landmarks`` on real images and the real video, and on broken inputs (never a traceback)."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from posed.cli import main
from posed.landmarks import read_recording


@pytest.fixture(autouse=True)
def _models(models_dir, monkeypatch):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))


def _pose_jpg(shared_data):
    return shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg"


def test_image_to_recording(shared_data, tmp_path, capsys):
    out = tmp_path / "pose.landmarks.jsonl"
    assert main(["landmarks", str(_pose_jpg(shared_data)), "-o", str(out)]) == 0
    header, frames, problems = read_recording(out)
    assert problems == [] and header.image_size == (1000, 667) and header.fps == 30.0
    assert "pose.jpg" in header.source
    assert len(frames) == 1 and frames[0].seq == 0 and frames[0].t == 0.0
    expected = json.loads((_pose_jpg(shared_data).parent / "pose_test_py_expected.json").read_text())
    err = np.linalg.norm(frames[0].landmarks[:, :2] - np.array(expected["EXPECTED_POSE_LANDMARKS"]), axis=1)
    assert err.max() < 15
    assert "1 frame(s), person found in 1" in capsys.readouterr().err


def test_image_to_stdout(shared_data, capsys):
    assert main(["landmarks", str(_pose_jpg(shared_data))]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2
    assert json.loads(lines[0])["format"] == "posed.landmarks" and len(json.loads(lines[1])["landmarks"]) == 33


def test_video_uses_its_frame_timestamps(shared_data, tmp_path):
    out = tmp_path / "squats.landmarks.jsonl"
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    assert main(["landmarks", str(video), "-o", str(out)]) == 0
    header, frames, problems = read_recording(out)
    assert problems == [] and header.image_size == (720, 1280) and header.fps == pytest.approx(5.0)
    assert [f.seq for f in frames] == list(range(65))
    assert [f.t for f in frames[:3]] == pytest.approx([0.0, 0.2, 0.4])
    assert all(f.landmarks is not None for f in frames)
    # written to the microsecond: 0.6, not seq / fps's 0.6000000000000001
    times = [json.loads(line)["t"] for line in out.read_text().splitlines()[1:]]
    assert times[3] == 0.6 and times[7] == 1.4 and all(t == round(t, 6) for t in times)


def test_folder_with_a_corrupt_image_reports_it_and_goes_on(shared_data, tmp_path, capsys):
    folder = tmp_path / "frames"
    folder.mkdir()
    shutil.copy(_pose_jpg(shared_data), folder / "a.jpg")
    (folder / "b.jpg").write_bytes(b"\xff\xd8\xff\xe0 not really a jpeg")
    shutil.copy(_pose_jpg(shared_data), folder / "c.jpg")
    (folder / "notes.txt").write_text("ignored")
    out = tmp_path / "f.landmarks.jsonl"
    assert main(["landmarks", str(folder), "-o", str(out), "--fps", "10"]) == 1
    err = capsys.readouterr().err
    assert "b.jpg: cannot decode the image" in err and "1 problem(s) reported above" in err
    header, frames, _ = read_recording(out)
    assert header.fps == 10.0
    assert [(f.seq, f.t) for f in frames] == [(0, 0.0), (2, 0.2)]
    assert all(f.landmarks is not None for f in frames)


def test_fake_and_truncated_videos_are_reported(shared_data, tmp_path, capsys):
    fake = tmp_path / "fake.mp4"
    fake.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 4)
    assert main(["landmarks", str(fake), "-o", str(tmp_path / "x.jsonl")]) == 2
    assert "fake.mp4: cannot open as a video" in capsys.readouterr().err

    # a real 10-frame MJPG AVI cut after about half of its bytes
    cap = cv2.VideoCapture(str(shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"))
    video = tmp_path / "squats.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, (720, 1280))
    for _ in range(10):
        writer.write(cap.read()[1])
    writer.release()
    cap.release()
    cut = tmp_path / "cut.avi"
    data = video.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.55)])
    out = tmp_path / "cut.landmarks.jsonl"
    assert main(["landmarks", str(cut), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "cut.avi: the video ended after" in err and "of 10 frames (truncated or corrupt)" in err
    _, frames, problems = read_recording(out)
    assert problems == [] and 1 <= len(frames) < 10 and all(f.landmarks is not None for f in frames)


def test_missing_input_and_models(tmp_path, capsys, monkeypatch, shared_data):
    assert main(["landmarks", str(tmp_path / "nothing.mp4")]) == 2
    assert "no such file or folder" in capsys.readouterr().err
    monkeypatch.setenv("POSED_MODELS_DIR", str(tmp_path / "no-models"))
    assert main(["landmarks", str(_pose_jpg(shared_data)), "-o", str(tmp_path / "o.jsonl")]) == 2
    assert "posed models fetch" in capsys.readouterr().err
