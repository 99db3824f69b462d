"""The real-video protocol with 3D truth (bench.balancing_video): the calibration is read the right way round
(the triangulated joints project onto what posed's landmark stage finds in every view), the scores are zero
for the truth itself, and a run gives every view, mode and rate with the fit and BlazePose's world landmarks
scored on the same frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from posed.bench import balancing_video as B
from posed.bench import ood as O
from posed.bench.mocap_landmarks import BODY12_IDX
from posed.landmarks import read_recording

# A wrong axis order or camera convention puts the joints hundreds of pixels off. 60 px is 13 cm at the
# man's 3.6 m from the cameras (f = 1680 px): over four times the truth's own 2-3 cm floor (data README)
# beside MediaPipe's 15 px tolerance for its own landmarks (pose_test_py_expected.json).
PROJECTION_PX = 60.0


@pytest.fixture(scope="module")
def folder(shared_data):
    return shared_data / B.DATA


@pytest.fixture(scope="module")
def recordings(folder, tmp_path_factory):
    """posed's landmark stage on the four views (the models `make test` fetched)."""
    cache = tmp_path_factory.mktemp("balancing")
    return cache, {n: B.landmark_recording(folder / "balancing" / f"{n}.mp4", cache) for n in B.CAMERAS}


def test_the_truth_projects_onto_the_landmarks_in_every_view(folder, recordings):
    cameras = B.load_cameras(folder)
    truth = B.load_truth(folder)
    assert truth.shape == (100, 12, 3)
    for name, path in recordings[1].items():
        cam = cameras[name]
        _, frames, _ = read_recording(path)
        errs = []
        for i in range(0, 100, 10):
            px, _ = cv2.projectPoints(truth[i], cv2.Rodrigues(cam.rot)[0], cam.t, cam.k, cam.dist)
            errs.append(np.linalg.norm(px[:, 0] - frames[i].landmarks[BODY12_IDX, :2], axis=1))
        assert np.median(errs) < PROJECTION_PX, (name, np.median(errs))
        assert (cam.to_camera(truth[0])[:, 2] > 1.0).all()                  # in front of the camera
        assert np.allclose(cam.to_world(cam.to_camera(truth[0])), truth[0])


def test_undistorting_with_no_distortion_changes_nothing(folder):
    cam = B.load_cameras(folder)["cam01"]
    plain = B.Camera(cam.name, cam.k, np.zeros(4), cam.rot, cam.t)
    lms = np.column_stack([np.random.default_rng(1).uniform(0, 1000, (33, 2)), np.ones((33, 3))])
    lms[5] = np.nan
    out = plain.undistort(lms)
    assert np.allclose(out[~np.isnan(lms[:, 0])], lms[~np.isnan(lms[:, 0])], atol=1e-6)
    assert np.isnan(out[5]).all()
    moved = cam.undistort(lms)
    assert not np.allclose(moved[:5, :2], lms[:5, :2], atol=1e-9)           # the real calibration moves them


def test_the_truth_scores_zero_and_a_mirrored_limb_counts_as_a_flip(folder):
    cam = B.load_cameras(folder)["cam01"]
    truth = cam.to_camera(B.load_truth(folder)[0])
    s = B._Scores()
    s.add(truth, truth)
    summary = s.summary()
    assert summary["pa_mpjpe_mm"] == 0 and summary["mpjpe_hip_aligned_mm"] == 0 and summary["angle_err_deg"] == 0
    assert summary["per_angle_deg"] == {a: {"abs": 0.0, "signed": 0.0} for a in O.ANGLE_NAMES}
    # the distal segment (forearm or shank) most inclined in depth, its end mirrored about its start
    from posed.bench.ood import SEGMENTS

    distal = [(a, b) for a, b in SEGMENTS if b in (4, 5, 10, 11)]
    a, b = max(distal, key=lambda ab: abs(truth[ab[1], 2] - truth[ab[0], 2]))
    dz = truth[b, 2] - truth[a, 2]
    assert abs(dz) > 0.05                          # a segment the flip count looks at
    mirrored = truth.copy()
    mirrored[b, 2] = truth[a, 2] - dz
    s2 = B._Scores()
    s2.add(mirrored, truth)
    counted = sum(abs(truth[q, 2] - truth[p, 2]) > 0.05 for p, q in SEGMENTS)
    assert s2.flips == [1, counted]
    # the per-angle errors are the same frame's angles, signed as estimate - truth, and average to angle_err_deg
    moved = O.segment_angles(mirrored) - O.segment_angles(truth)
    per = s2.summary()["per_angle_deg"]
    assert [per[a]["signed"] for a in O.ANGLE_NAMES] == pytest.approx(moved, abs=0.051)
    assert [per[a]["abs"] for a in O.ANGLE_NAMES] == pytest.approx(np.abs(moved), abs=0.051)
    assert np.mean([per[a]["abs"] for a in O.ANGLE_NAMES]) == pytest.approx(s2.summary()["angle_err_deg"], abs=0.06)
    assert any(abs(v) > 1.0 for v in moved)        # the mirrored segment bends a joint


def test_a_run_scores_the_fit_and_blazepose_on_the_same_frames(shared_data, recordings):
    rows = B.run(shared_data, cache=recordings[0])
    assert {(r["view"], r["mode"], r["fps"]) for r in rows} == {
        (v, m, f) for v in (*B.CAMERAS, "all") for m, f in B.RUNS}
    # the 10 fps video run again with each camera's gravity (fitting.vertical): the four views, filmed from
    # 18-25 degrees above, agree better on the hips' share of the pelvis-hip-lumbar split they cannot observe
    with_gravity = [r for r in rows if r.get("gravity")]
    assert [(r["view"], r["mode"], r["fps"], r["gravity"]) for r in with_gravity] == [
        ("all", *B.GRAVITY_RUN, "calibration")]
    as_before = next(r for r in rows if r["view"] == "all" and (r["mode"], r["fps"]) == B.GRAVITY_RUN
                     and not r.get("gravity"))
    hips = ("theta_hp_l", "theta_hp_r")
    assert sum(with_gravity[0]["views_split_spread_deg"][a] for a in hips) < \
        sum(as_before["views_split_spread_deg"][a] for a in hips), (with_gravity, as_before)
    for r in rows:
        assert r["answered"] == r["frames"] > 0                              # the man is in every frame
        for who in ("fit", "blazepose_world"):
            assert 0 < r[who]["pa_mpjpe_mm"] < 1000 and 0 <= r[who]["depth_flips"] <= 1
            per = r[who]["per_angle_deg"]
            assert list(per) == list(O.ANGLE_NAMES)
            assert all(0 < p["abs"] < 180 and abs(p["signed"]) <= p["abs"] + 0.05 for p in per.values()), per
            # the eight angles' mean is the row's angle error (each rounded to 0.1 first)
            assert np.mean([p["abs"] for p in per.values()]) == pytest.approx(r[who]["angle_err_deg"], abs=0.1)
    overall = [r for r in rows if r["view"] == "all"]
    for r in overall:
        assert r["fit_over_blazepose_pa"] == pytest.approx(r["fit"]["pa_mpjpe_mm"] / r["blazepose_world"]["pa_mpjpe_mm"],
                                                           abs=1e-3)
        assert r["root_err_mm"] is not None and r["views_root_spread_mm"] is not None
        # the 2D landmarks at the true depths leave far less than at any estimate's depths
        depth = r["depth_sources"]
        assert 0 < depth["true"] < 0.8 * min(depth["world"], depth["fit"]), depth
    assert len(B.markdown(rows)) == 2 + len(B.RUNS) + 1   # and the gravity row
    # each angle a line, each four-view row a column; the cells are the rows' own numbers
    table = B.per_angle_markdown(rows)
    assert len(table) == 2 + len(O.ANGLE_NAMES) and table[1].count("---") == 1 + len(overall)
    first = overall[0]["fit"]["per_angle_deg"]["knee_l"]
    assert table[2].startswith("| knee_l | ") and f"{first['abs']} / {first['signed']:+}; " in table[2]
    # the baseline is the landmark stage with MediaPipe's own left/right labels, at each rate the fit runs at;
    # at 10 fps one run per starting frame (0-5), so that every frame is scored once
    names = sorted(p.name for p in recordings[0].glob("*.landmarks.jsonl"))
    runs = sum(round(B.VIDEO_FPS / f) for f in {f for _, f in B.RUNS})    # 1 at 60 fps + 6 at 10 fps
    assert sum(".mediapipe." in n for n in names) == len(B.CAMERAS) * runs
    assert sum(".every6" in n for n in names) == 2 * 6 * len(B.CAMERAS)
    by_rate = {f: sum(r["frames"] for r in rows if r["view"] != "all" and r["fps"] == f and r["mode"] == "video")
               for f in (10.0, 60.0)}
    assert by_rate[10.0] == by_rate[60.0] == 4 * 100, by_rate       # every frame of every view, at both rates
    # other extractors' recordings (MediaPipe's labels) through `posed fit`'s side check: camera 2's flips put back
    external = [r for r in overall if "external_recordings" in r]
    assert [(r["mode"], r["fps"]) for r in external] == [B.EXTERNAL_RUN]
    ext = external[0]["external_recordings"]
    assert ext["frames"] == {"as_they_come": 400, "sides_put_back": 400} and ext["frames_put_back"] >= 10
    assert ext["fit_pa_mpjpe_mm"]["sides_put_back"] < ext["fit_pa_mpjpe_mm"]["as_they_come"] - 5.0, ext


def test_camera_2_at_the_daemons_rate_keeps_left_and_right_where_mediapipe_flips_them(folder, recordings):
    """pose2sim's camera 2 through the landmark stage at 10 fps (every 6th frame): against the man's
    triangulated joints projected into the view, BlazePose's own labels have his left and right swapped on
    several frames; with the sides kept (landmarks.sides, the default) on none."""
    cam = B.load_cameras(folder)["cam02"]
    truth = B.load_truth(folder)
    video = folder / "balancing" / "cam02.mp4"
    mirror = np.array([1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10])
    wrong = {}
    for mediapipe in (True, False):
        view = B._load_view(cam, B.landmark_recording(video, recordings[0], mediapipe_sides=mediapipe, step=6),
                            truth)
        k = cam.intrinsics(view.image_size)
        wrong[mediapipe] = []
        for i in range(0, len(truth), 6):
            lm = view.landmarks[i]
            assert lm is not None, i
            t = view.truth_cam[i]
            uv = np.column_stack([t[:, 0] / t[:, 2] * k.fx + k.cx, t[:, 1] / t[:, 2] * k.fy + k.cy])
            p = lm[BODY12_IDX, :2]
            if np.linalg.norm(p[mirror] - uv, axis=1).mean() < np.linalg.norm(p - uv, axis=1).mean():
                wrong[mediapipe].append(i)
    assert len(wrong[True]) >= 3, wrong
    assert wrong[False] == [], wrong
