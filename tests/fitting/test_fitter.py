"""Fitter: recovery of known poses, determinism, video mode, perspective, bad input, real landmarks."""

import json

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.camera_model import Intrinsics
from posed.fitting.config import FitConfig
from posed.fitting.fitter import Fitter
from posed.fitting.result import JOINT_3D_NAMES, JOINT_ANGLE_NAMES, VARIABLE_NAMES, FitResult

SIZE = (640, 480)


@pytest.fixture(scope="module")
def fitter():
    f = Fitter(FitConfig())
    f.warmup()
    return f


def angle_error(result, pose) -> float:
    truth = pose.variables()
    return float(np.mean([abs((result.variables[k] - truth[k] + 180) % 360 - 180) for k in VARIABLE_NAMES[1:]]))


@pytest.mark.parametrize(("name", "yaw"), [("stand_arms_front", 25.0), ("walk_left_forward", 35.0),
                                           ("bend_grab", 40.0), ("sit_chair", 30.0), ("kneel", 20.0),
                                           ("lying_back", -30.0), ("fallen_backward", 150.0),
                                           ("sitting_floor_knees_up", 90.0)])
def test_recovers_known_poses(fitter, name, yaw):
    pose = S.pose(name, yaw)
    r = fitter.fit(S.render(pose), 0, 0.0, SIZE, mode="image")
    assert r.ok, r.reason
    assert angle_error(r, pose) < 0.5, (name, r.variables)
    truth = S.ground_truth(pose, S.body_dimensions(1.6))
    err3d = np.mean([np.linalg.norm(np.subtract(r.joints_3d[k], truth.joints_3d[k])) for k in JOINT_3D_NAMES])
    assert err3d < 0.005
    assert r.extra["err2d_px"] < 0.05


def test_result_follows_the_interface(fitter):
    pose = S.pose("sit_chair", 30.0)
    r = fitter.fit(S.render(pose), 7, 1.25, SIZE, mode="image")
    obj = json.loads(json.dumps(r.to_json()))
    assert obj["seq"] == 7 and obj["t"] == 1.25 and obj["ok"] is True
    assert list(obj["variables"]) == list(VARIABLE_NAMES)
    assert set(obj["joint_angles_deg"]) == set(JOINT_ANGLE_NAMES)
    assert list(obj["joints_3d"]) == list(JOINT_3D_NAMES) and obj["joints_3d"]["mid_hip"] == [0, 0, 0]
    # gamma: the apparent standing height over the image height (the render fills 60 %)
    assert obj["variables"]["gamma"] == pytest.approx(S.FILL, rel=1e-3)
    # camera-aligned: the sitting person's knees are nearer the camera than the hips, the head above
    j = obj["joints_3d"]
    assert j["left_knee"][2] < j["left_hip"][2] and j["left_shoulder"][1] < 0
    assert FitResult.from_json(obj).variables == r.variables
    assert isinstance(obj["loss"], float) and obj["fit_ms"] > 0


def test_same_seed_same_result():
    lm = S.render(S.pose("walk_left_forward", 30.0), noise_px=3.0, seed=4)
    a = Fitter(FitConfig(seed=3)).fit(lm, 0, 0.0, SIZE, mode="image")
    b = Fitter(FitConfig(seed=3)).fit(lm, 0, 0.0, SIZE, mode="image")
    assert a.variables == b.variables and a.loss == b.loss


def test_video_mode_tracks_a_fall(fitter):
    fitter.reset()
    frames = S.render_sequence(S.sequence("fall_sideways", 30.0), fps=30)
    errors, modes = [], []
    for i, (t, lm, pose) in enumerate(frames):
        r = fitter.fit(lm, i, t, SIZE, mode="video")
        assert r.ok, r.reason
        errors.append(angle_error(r, pose))
        modes.append(r.extra["mode"])
    assert modes[0] == "image" and modes.count("video") >= len(frames) - 3
    assert np.mean(errors) < 1.0 and max(errors) < 5.0
    fitter.reset()
    assert fitter.fit(frames[5][1], 5, frames[5][0], SIZE, mode="video").extra["mode"] == "image"


def test_perspective_with_intrinsics(fitter):
    cam = S.LevelCamera(model="pinhole", distance_m=3.0)
    pose = S.pose("bend_grab", 30.0)
    lm = S.render(pose, camera=cam)
    r = fitter.fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=cam.intrinsics(SIZE))
    assert r.ok and r.extra["projection"] == "perspective"
    assert angle_error(r, pose) < 0.5
    # without intrinsics the orthographic model cannot fit the perspective image exactly
    r2 = fitter.fit(lm, 0, 0.0, SIZE, mode="image")
    assert r2.extra["projection"] == "orthographic" and r2.extra["err2d"] > 10 * r.extra["err2d"]
    assert r.extra["lens"] == "given" and r.root_cam_m is not None and "lens" not in r2.extra


def test_an_assumed_lens_projects_in_perspective_without_metres(fitter):
    """The lens the daemon assumes for a source without intrinsics (camera_model.Intrinsics.assume): the fit
    projects through it like the camera's own, but publishes no position in metres."""
    cam = S.LevelCamera(model="pinhole", distance_m=3.0)
    pose = S.pose("bend_grab", 30.0)
    lm = S.render(pose, camera=cam)
    true = cam.intrinsics(SIZE)
    assumed = Intrinsics(true.fx, true.fy, true.cx, true.cy, *SIZE, assumed=True)   # right by luck
    r = fitter.fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=assumed)
    assert r.ok and r.extra["projection"] == "perspective" and r.extra["lens"] == "assumed"
    assert r.root_cam_m is None and "root_cam_m" not in r.to_json()
    assert angle_error(r, pose) < 0.5                       # the same projection as the measured lens
    wide = fitter.fit(lm, 0, 0.0, SIZE, mode="image", intrinsics=Intrinsics.assume(69.0, *SIZE))
    assert wide.ok and wide.extra["lens"] == "assumed" and wide.root_cam_m is None


def test_bad_inputs_never_raise(fitter):
    good = S.render(S.pose("stand_arms_front", 30.0))
    r = fitter.fit(None, 1, 0.1, SIZE)
    assert not r.ok and r.reason == "no person"
    nan = good.copy()
    nan[[25, 27]] = np.nan
    nan[26, 3] = 0.1
    nan[11] = np.nan
    nan[23, 0] = np.inf
    r = fitter.fit(nan, 2, 0.2, SIZE)
    assert not r.ok
    for name in ("left_knee", "left_ankle", "right_knee", "left_shoulder", "left_hip"):
        assert name in r.reason
    assert fitter.fit(np.zeros((33, 4)), 3, 0.3, SIZE).reason.startswith("landmarks must be a (33, 5) array")
    assert "collapse" in fitter.fit(np.ones((33, 5)), 4, 0.4, SIZE).reason
    assert not fitter.fit(good, 5, 0.5, (0, 480)).ok
    assert not fitter.fit(good, 6, 0.5, SIZE, mode="sideways").ok
    assert not fitter.fit("garbage", 7, 0.5, SIZE).ok
    assert not fitter.fit(good, 8, 0.5, SIZE, intrinsics=(0, 1, 2)).ok
    rnd = np.random.default_rng(0).uniform(0, 640, (33, 5))
    rnd[:, 3:] = 1.0
    r = fitter.fit(rnd, 9, 0.6, SIZE, mode="image")
    assert not r.ok and "fit rejected" in r.reason


def test_partial_landmarks_fit_what_is_usable(fitter):
    pose = S.pose("sit_chair", 30.0)
    lm = S.render(pose)
    lm[28] = np.nan  # right ankle unknown
    r = fitter.fit(lm, 0, 0.0, SIZE, mode="image")
    assert r.ok
    assert r.extra["missing"] == ["right_ankle"] and r.extra["unobserved"] == ["theta_kn_r"]
    truth = pose.variables()
    for k in VARIABLE_NAMES[1:]:
        if k != "theta_kn_r":
            assert abs(r.variables[k] - truth[k]) < 1.0, k


def test_real_squat_video_landmarks(shared_data):
    """BlazePose landmarks of a real squat video (tfjs-models): hip and knee flexion swing from near 0
    (standing) to deep flexion (squatting), and the model reprojects onto the landmarks."""
    path = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.full.json"
    frames = json.loads(path.read_text())
    fitter = Fitter(FitConfig(body_height_m=1.65))
    knees, hips, err = [], [], []
    for i, pts in enumerate(frames):
        arr = np.asarray(pts, dtype=float)
        lm = np.column_stack([arr, np.ones(33), np.ones(33)])
        r = fitter.fit(lm, i, i / 5.0, (720, 1280), mode="video")
        assert r.ok, r.reason
        knees.append(0.5 * (r.variables["theta_kn_l"] + r.variables["theta_kn_r"]))
        hips.append(0.5 * (r.variables["theta_hp_l"] + r.variables["theta_hp_r"]))
        err.append(r.extra["err2d"])
    assert min(knees) < 25 and max(knees) > 80
    assert min(hips) < 20 and max(hips) > 60
    # The typical frame reprojects within the product's own tracking criterion. A residual above
    # fitting.pose_prior_max_noise (0.015 of body height) is what the product calls a model mismatch rather
    # than landmark noise, and this video has one the model cannot represent (knees turned out, no hip axial
    # rotation: docs/body-model.md, "Model limits"), so its median sits at that cap (0.0149; ulp-level input
    # changes move it across 0.015, which is why the cap itself cannot be the bound). Twice the cap is
    # fitting.video_recover_error (0.03): above it the fitter itself treats a video frame as a lost track and
    # fits it again. A wrong basin is caught by the knee and hip ranges above; every frame is also within
    # max_error (0.05), or r.ok fails.
    assert np.median(err) < fitter.config.video_recover_error
