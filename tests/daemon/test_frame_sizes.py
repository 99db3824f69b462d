"""Cameras as people have them (issue 39), through the real daemon (real model, fit, Zenoh on 127.0.0.1):
every real clip of the shared data at its own size, orientation and rate, paced as a camera would be; a
1920x1080 and a 1080x1920 source scaled down at capture with landmarks in the source's own pixels; 5 and 60 fps
sources made from real video; a source whose every frame fails: ``blind`` in the status and in STATUS=, and a
non-zero exit with the reason."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from posed.client import contract
from tests.daemon.frame_sizes_util import frames_taken, read_frames, run_to_end, write_video

REF = Path("reference")
BODY = [11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28]
SLOT = 1280 * 720                       # pipeline.frame_max_pixels, the default working size


def _size(path: Path) -> tuple[int, int, float, int]:
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    ok, image = cap.read()
    fps, n = cap.get(cv2.CAP_PROP_FPS), int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    cap.release()
    assert ok, path
    return image.shape[1], image.shape[0], fps, n


def _check_published(run, w: int, h: int, expected_poses: int) -> None:
    assert run.code == 0, run.stderr[-3000:]
    poses, lms = run.got["pose"], run.got["landmarks"]
    assert len(poses) >= 0.9 * expected_poses, (len(poses), expected_poses)
    assert sum(1 for p in poses if p.get("ok")) > 0
    assert lms and all(m["image_size"] == [w, h] for m in lms), lms[0]["image_size"]
    statuses = run.got["status"]
    assert statuses and all(contract.errors(s) == [] for s in statuses[-3:]), contract.errors(statuses[-1])
    cams = [s["camera"] for s in statuses if "working_width" in s["camera"]]
    k = 1
    while (w // k) * (h // k) > SLOT:
        k += 1
    assert cams and (cams[-1]["frame_width"], cams[-1]["frame_height"]) == (w, h)
    assert (cams[-1]["working_width"], cams[-1]["working_height"], cams[-1]["scale"]) == (w // k, h // k, k)
    assert cams[-1]["kind"] == "file"
    assert not [s for s in statuses if s["state"] == "blind"], [s["blind"] for s in statuses if s.get("blind")]
    assert run.events("recording_open") and not run.events("camera_open")
    assert not run.events("frame_skipped")
    assert not [t for t in run.notify if "camera open" in t], run.notify[-2:]


@pytest.mark.parametrize("clip", [
    "multi_person/s2d_enter.mp4",             # 1768x994, 30 fps: scaled by 2
    "multi_person/bend_hand.mp4",             # 1080x1920 portrait, 12 fps: scaled by 2
    "multi_person/store_aisle.gif",           # 480x270 GIF, 16.7 fps: as it is
    "pose2sim_demo/balancing/cam01.mp4",      # 1080x1920, 60 fps
    "pose2sim_demo/balancing/cam03.mp4",      # 1088x1920, 60 fps
])
def test_every_real_clip_publishes_poses_paced(tmp_path, shared_data, clip):
    """The default config, paced as a camera: a pose for at least 90 % of the frames the capture stage takes
    (10 fps, or the clip's own rate where lower), landmarks in the clip's own pixels."""
    path = shared_data / REF / clip
    w, h, fps, n = _size(path)
    run = run_to_end(tmp_path, f"file:{path}")
    _check_published(run, w, h, frames_taken(n, fps))


def _reference_landmarks(image: np.ndarray) -> np.ndarray | None:
    from posed.daemon.config import Config
    from posed.landmarks import PoseLandmarker

    lm = PoseLandmarker(Config().landmarks)
    return lm.process(image, 0.0, 0).landmarks


def test_a_portrait_1088x1920_source_reports_landmarks_in_its_own_pixels(tmp_path, shared_data):
    """cam03 (one man, 1088x1920) is worked on at 544x960; the published landmarks of its first frame agree
    with BlazePose run on the full-size frame to within 3 % of his height (at the working size's pixels, not
    scaled back, they would be off by half the image)."""
    path = shared_data / REF / "pose2sim_demo/balancing/cam03.mp4"
    frames = read_frames(path, 20)
    run = run_to_end(tmp_path, f"file:{path}", "source.realtime=false")
    assert run.code == 0, run.stderr[-3000:]
    by_seq = {m["seq"]: m for m in run.got["landmarks"] if m.get("landmarks")}
    seq = min(by_seq)
    got = np.array([[np.nan] * 5 if r is None else r for r in by_seq[seq]["landmarks"]], float)
    ref = _reference_landmarks(frames[seq])
    assert ref is not None
    height = np.ptp(ref[BODY, 1])
    err = np.linalg.norm(got[BODY, :2] - ref[BODY, :2], axis=1) / height
    assert height > 300 and np.nanmedian(err) < 0.03, (height, np.round(err, 3))


def test_a_1920x1080_source_is_worked_on_at_960x540(tmp_path, shared_data):
    """A full-HD landscape recording (the real s2d_enter clip at 1920x1080, as a 1080p camera gives it): poses
    published paced at 10 fps, the ring holds 960x540, landmarks reach below row 540 (the source's pixels)."""
    frames = [cv2.resize(f, (1920, 1080), interpolation=cv2.INTER_CUBIC)
              for f in read_frames(shared_data / REF / "multi_person/s2d_enter.mp4", 90)]
    path = write_video(tmp_path / "fullhd.avi", frames, 30.0)
    run = run_to_end(tmp_path, f"file:{path}")
    _check_published(run, 1920, 1080, frames_taken(len(frames), 30.0))
    ys = [r[1] for m in run.got["landmarks"] if m.get("landmarks") for r in m["landmarks"] if r]
    assert max(ys) > 540, max(ys)        # the man's feet, below the working frame's 540 rows


def _steps(poses: list[dict]) -> list[float]:
    ts = sorted(p["t"] for p in poses)
    return [b - a for a, b in zip(ts, ts[1:], strict=False)]


def test_a_5_fps_source_gives_every_frame(tmp_path, shared_data):
    """CCTV rate: a 5 fps recording (every sixth frame of the real 30 fps s2d_enter clip) is taken whole:
    a pose every 0.2 s of capture time."""
    frames = read_frames(shared_data / REF / "multi_person/s2d_enter.mp4", 20, step=6)
    path = write_video(tmp_path / "cctv.avi", frames, 5.0)
    run = run_to_end(tmp_path, f"file:{path}")
    _check_published(run, 1768, 994, len(frames))
    assert float(np.median(_steps(run.got["pose"]))) == pytest.approx(0.2, abs=0.01)


def test_a_60_fps_source_is_paced_to_10_fps(tmp_path, shared_data):
    """A 60 fps recording (the real clip, each frame shown twice) is thinned to the 10 fps budget by capture
    time: a pose every 0.1 s, five of six frames skipped, none dropped for being late."""
    frames = [f for f in read_frames(shared_data / REF / "multi_person/s2d_enter.mp4", 60) for _ in range(2)]
    path = write_video(tmp_path / "fast.avi", frames, 60.0)
    run = run_to_end(tmp_path, f"file:{path}")
    _check_published(run, 1768, 994, frames_taken(len(frames), 60.0))
    assert float(np.median(_steps(run.got["pose"]))) == pytest.approx(0.1, abs=0.01)
    cap = run.got["status"][-1]["stages"]["capture"]
    assert cap["skipped"] >= 0.75 * len(frames), cap


def test_a_source_whose_frames_all_fail_is_blind_and_exits_non_zero(tmp_path, shared_data):
    """A folder of real frames cut short (JPEGs whose image data was lost: none decodes), replayed paced at 5 fps:
    the status says blind with the reason and the fix, STATUS= says it, the log has blind error lines, and the
    run ends with exit 65 and the reason on stderr."""
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, f in enumerate(read_frames(shared_data / REF / "multi_person/s2d_enter.mp4", 30)):
        ok, jpg = cv2.imencode(".jpg", f)
        assert ok
        data = jpg.tobytes()
        (folder / f"frame_{i:03d}.jpg").write_bytes(data[:data.index(b"\xff\xda")])   # cut before the scan
    run = run_to_end(tmp_path, f"file:{folder}", "source.fps=5")
    assert run.code == 65, (run.code, run.stderr[-2000:])
    assert "none of its frames reached the landmarks stage" in run.stderr, run.stderr[-2000:]
    assert "replace or delete the image" in run.stderr, run.stderr[-2000:]
    blind = [s for s in run.got["status"] if s["state"] == "blind"]
    assert blind, [s["state"] for s in run.got["status"]]
    assert all(contract.errors(s) == [] for s in blind[-2:]), contract.errors(blind[-1])
    assert "skipped as unusable" in blind[-1]["blind"]["reason"] and blind[-1]["blind"]["fix"]
    assert any(t.startswith("STATUS=blind: ") and "skipped" in t for t in run.notify), run.notify[-3:]
    lines = run.events("blind")
    assert lines and all(x["level"] == "error" and x["fix"] for x in lines)
    assert len(lines) <= 3, len(lines)           # one per logging.stats_period_s (10 s), not one per frame


def test_a_landmark_recording_whose_every_frame_is_broken_exits_non_zero(tmp_path, shared_data):
    """A real recording's header with every frame line cut in half: nothing reaches the fitting stage, so the run
    says why and exits 65, never 0."""
    lines = (shared_data / "falls" / "urfd_dev" / "urfd_16_adl.landmarks.jsonl").read_text().splitlines()
    rec = tmp_path / "broken.landmarks.jsonl"
    rec.write_text("\n".join([lines[0]] + [x[: len(x) // 2] for x in lines[1:40]]) + "\n")
    run = run_to_end(tmp_path, f"file:{rec}", "source.realtime=false")
    assert run.code == 65, (run.code, run.stderr[-2000:])
    assert "none of its frames reached the fitting stage" in run.stderr, run.stderr[-2000:]
    assert "fix: repair or re-record the recording" in run.stderr, run.stderr[-2000:]
