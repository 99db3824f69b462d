"""`posed render` on the real squat video: the output decodes, has every frame, and the fitted skeleton is
drawn on the person (inside the box of the reference BlazePose landmarks, tfjs-models' own output)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.cli import main
from posed.viz.reproject import reproject

FRAMES = 65          # pose_squats.mp4 (data README)
SIZE = (720, 1280)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory, shared_data):
    out = tmp_path_factory.mktemp("render") / "squat.webm"
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    assert main(["render", str(video), "-o", str(out), "--max-height", "0"]) == 0   # full size: pixels compared
    return out, video


def _frames(path):
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        out.append(f)
    cap.release()
    return out


def _skeleton_mask(img: np.ndarray) -> np.ndarray:
    """Pixels in the fitted skeleton's saturated colours (orange left, blue right, green centre)."""
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    strong = (s > 150) & (v > 150)
    return strong & (((h >= 8) & (h <= 22)) | ((h >= 95) & (h <= 110)) | ((h >= 50) & (h <= 70)))


@pytest.mark.slow
def test_render_plays_every_frame_with_a_side_view(rendered):
    out, _ = rendered
    frames = _frames(out)
    assert len(frames) == FRAMES
    w, h = SIZE
    assert frames[0].shape[0] == h and frames[0].shape[1] > w   # the image plus the side view beside it


@pytest.mark.slow
def test_drawn_skeleton_lies_on_the_person(rendered, shared_data):
    out, video = rendered
    ref = json.loads((shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.full.json").read_text())
    drawn, source = _frames(out), _frames(video)
    assert len(drawn) == len(source) == len(ref) == FRAMES
    w, h = SIZE
    s = min(w, h) / 640.0
    checked = 0
    for img, src, lms in zip(drawn, source, ref, strict=True):
        pts = np.array(lms, float)[:, :2]
        lo, hi = pts.min(0), pts.max(0)
        # margin: a joint dot's radius and a line's half width (viz.overlay, 5 s and 2 s px) plus the fit's
        # largest accepted 2D error, 5 % of the body height (fitting.max_error)
        margin = 7 * s + 0.05 * (hi[1] - lo[1])
        mask = _skeleton_mask(img[:, :w]) & ~_skeleton_mask(src)
        mask[: int(240 * s), : int(340 * s)] = False          # the angle table (coloured text)
        mask[h - int(100 * s):, :] = False                     # the key and the reprojection note
        ys, xs = np.nonzero(mask)
        if len(xs) < 100:
            continue
        inside = (xs >= lo[0] - margin) & (xs <= hi[0] + margin) & (ys >= lo[1] - margin) & (ys <= hi[1] + margin)
        assert inside.mean() > 0.97, f"{(~inside).sum()} skeleton pixels off the person"
        checked += 1
    assert checked >= FRAMES - 5   # the person is in every frame; a frame or two may have no fit


def test_perspective_reprojection_is_the_pinhole_of_the_fitted_joints():
    cam = Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480)
    joints = {"mid_hip": (0.0, 0.0, 0.0), "left_knee": (0.1, 0.45, -0.05), "left_shoulder": (0.18, -0.5, 0.02)}
    root = (0.3, 0.1, 3.0)
    r = reproject(joints, root, cam, None)
    assert r.how == "perspective"
    for name, p in joints.items():
        x, y, z = (np.array(p) + np.array(root))
        assert r.pixels[name] == pytest.approx((600 * x / z + 320, 600 * y / z + 240))


def test_orthographic_reprojection_recovers_scale_and_offset():
    joints = {"left_hip": (0.1, 0.0, 0.0), "right_hip": (-0.1, 0.0, 0.0), "left_knee": (0.12, 0.45, 0.0),
              "right_knee": (-0.1, 0.44, 0.1), "left_shoulder": (0.2, -0.5, 0.0)}
    lm = np.full((33, 5), np.nan)
    idx = {"left_hip": 23, "right_hip": 24, "left_knee": 25, "right_knee": 26, "left_shoulder": 11}
    for n, i in idx.items():
        lm[i] = (300 + 250 * joints[n][0], 200 + 250 * joints[n][1], 0, 1, 1)
    r = reproject(joints, None, None, lm)
    assert r.how.startswith("laid on the landmarks")
    for n, i in idx.items():
        assert r.pixels[n] == pytest.approx(tuple(lm[i, :2]))


def test_render_refuses_a_recording_without_its_fit(shared_data, tmp_path, capsys):
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    assert main(["render", str(rec), "-o", str(tmp_path / "x.webm")]) == 2
    assert "--fit" in capsys.readouterr().err


def test_render_a_recording_with_its_fit_every_frame_perspective(shared_data, tmp_path, capsys):
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    fit = tmp_path / "fit.jsonl"
    assert main(["fit", str(rec), "-o", str(fit)]) == 0
    out = tmp_path / "fall.webm"
    assert main(["render", str(rec), "--fit", str(fit), "-o", str(out), "--set", "falls.camera_height_m=0.85",
                 "--camera-height", "0.85"]) == 0
    assert "perspective reprojection" in capsys.readouterr().err     # the recording carries intrinsics
    frames = _frames(out)
    lines = rec.read_text().splitlines()
    assert len(frames) == len(lines) - 1                             # one per recorded frame (header excluded)
    assert frames[0].shape[0] == 480 and frames[0].shape[1] == 640 + 384   # the side panel: 0.8 h (a deep scene)


def test_render_reports_bad_inputs(tmp_path, capsys):
    assert main(["render", str(tmp_path / "none.mp4"), "-o", str(tmp_path / "x.webm")]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video at all" * 100)
    assert main(["render", str(bad), "-o", str(tmp_path / "x.webm")]) == 2
    assert "cannot open" in capsys.readouterr().err


@pytest.mark.slow
def test_render_draws_every_person_of_a_real_two_person_clip(shared_data, tmp_path):
    """The real s2d_enter clip cut to its first 3 s (a woman walks in at ~1.3 s): rendered in the daemon's
    several-people mode, the frames after she is found have the fitted skeleton drawn over both people: skeleton
    colours inside each person's own landmark box, the other person drawn where the one-person render left
    the picture as it was."""
    from posed.landmarks import LandmarkConfig, MultiPoseLandmarker
    from tests.daemon.frame_sizes_util import read_frames, write_video

    frames = read_frames(shared_data / "reference" / "multi_person" / "s2d_enter.mp4", n=90)
    clip = write_video(tmp_path / "enter.avi", frames, 30.0)
    out = tmp_path / "enter.webm"
    assert main(["render", str(clip), "-o", str(out), "--max-height", "0"]) == 0
    drawn = _frames(out)
    assert len(drawn) == 90
    # where the two people are, from the landmarker itself on the last frame
    lm = MultiPoseLandmarker(LandmarkConfig())
    for k, f in enumerate(frames):
        res = lm.process_full(f, k / 30.0, k)
    assert len(res.people) == 2
    h, w = frames[0].shape[:2]
    mask = _skeleton_mask(drawn[-1][:, :w])
    for person in res.people:
        marks = person.result.frame.landmarks
        ok = np.isfinite(marks[:, :2]).all(axis=1) & (marks[:, 3] > 0.5)
        x0, y0 = np.floor(marks[ok, :2].min(axis=0)).astype(int)
        x1, y1 = np.ceil(marks[ok, :2].max(axis=0)).astype(int)
        assert mask[max(0, y0):y1, max(0, x0):x1].sum() > 200, f"no skeleton drawn over person {person.id}"


def test_render_of_a_recording_draws_the_labels_its_fit_was_given(shared_data, tmp_path, capsys):
    """A recording another tool made, its labels flipped on three frames: `posed fit` put them back
    (landmarks.sides), so the landmarks `posed render` draws over the video are the put-back ones too —
    never a left arm drawn where the fitted skeleton has the right."""
    import argparse

    from posed.commands import config_from_args
    from posed.commands.render import _from_recording
    from posed.landmarks import read_recording
    from tests.landmarks import flipped_squat

    clean = flipped_squat.write(shared_data, tmp_path / "clean.landmarks.jsonl", flip=())
    flipped = flipped_squat.write(shared_data, tmp_path / "flipped.landmarks.jsonl")
    fit = tmp_path / "fit.jsonl"
    assert main(["fit", str(flipped), "-o", str(fit)]) == 0
    capsys.readouterr()
    args = argparse.Namespace(input=str(flipped), fit=str(fit), hfov=None, config=None)
    _size, _fps, _k, items, problems = _from_recording(args, config_from_args(args))
    _, truth, _ = read_recording(clean)
    assert problems == 0 and len(items) == len(truth)
    for (seq, _t, landmarks, own, _others), f in zip(items, truth, strict=True):
        np.testing.assert_array_equal(landmarks, f.landmarks, err_msg=f"seq {seq}")
        assert own is not None and own.seq == seq
