"""Video mode on real motion: BlazePose landmarks of a real squat video (tfjs-models' pose_squats, 5 fps),
fitted frame by frame in image mode and in video mode at 5, 10 and 30 fps (the video's frames repeated, as a
replay at the daemon's rate shows them). Video mode must follow the landmarks as well as image mode does:
no lag (the knees straighten between squats: before issue #13 video mode held them at 47-57 degrees where
image mode gives 3-20), no worse 2D error, and the same knee angles wherever image mode fits better."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed.fitting import FitConfig, Fitter

STANDING = [*range(20, 28), *range(43, 52)]  # between the squats: image mode gives knees of 3-20 degrees


@pytest.fixture(scope="module")
def squat(shared_data):
    frames = json.loads((shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.full.json").read_text())
    return [np.column_stack([np.asarray(p, float), np.ones(33), np.ones(33)]) for p in frames]


def fit_all(frames, mode: str, fps: float, dims=None) -> tuple[np.ndarray, np.ndarray, list]:
    """Mean knee flexion (degrees), 2D error (pixels) and the body's lengths of each video frame, replayed at
    ``fps``. ``dims``: one body per frame (image mode with those lengths) or None (the configured body)."""
    cfg = FitConfig(body_height_m=1.65)
    fitter = Fitter(cfg)
    repeat = round(fps / 5.0)
    knees, errors, bodies = [], [], []
    seq = 0
    for i, lm in enumerate(frames):
        if dims is not None:
            fitter = Fitter(cfg, dims=dims[i])
        for k in range(repeat):
            r = fitter.fit(lm, seq, i / 5.0 + k / fps, (720, 1280), mode=mode)
            seq += 1
            assert r.ok, r.reason
            if k == 0:
                knees.append(0.5 * (r.variables["theta_kn_l"] + r.variables["theta_kn_r"]))
                errors.append(r.extra["err2d_px"])
                bodies.append(fitter.dims)
    return np.array(knees), np.array(errors), bodies


@pytest.fixture(scope="module")
def image_mode(squat):
    return fit_all(squat, "image", 5.0)


@pytest.mark.parametrize("fps", [5.0, 10.0, 30.0])
def test_video_mode_follows_the_landmarks_at_any_frame_rate(squat, image_mode, fps):
    knee_c, err_c, _ = image_mode
    knee_v, err_v, bodies = fit_all(squat, "video", fps)
    # video mode learns the woman's proportions (fitting.proportions): image mode with the very lengths video
    # mode used at each frame is the reference for the pose, so that a different body is not taken for a lag
    knee_i, err_i, _ = fit_all(squat, "image", 5.0, dims=bodies)
    assert bodies[-1] != bodies[0]
    # no lag: between the squats the knees come back to a standing person's flexion
    for window in (STANDING[:8], STANDING[8:]):
        assert knee_v[window].min() < 25.0, f"{fps} fps: knees held at {knee_v[window].round(1)}"
    # the bottoms are reached: as deep as image mode within the 8 degrees of the target
    assert knee_v.max() > knee_i.max() - 8.0
    # no worse in 2D than image mode with either body: the median error is image mode's or lower; 2 % allows
    # one frame whose two depth hypotheses tie in 2D to be decided differently (a single frame moves the median
    # of 65 by < 0.2 px)
    assert np.median(err_v) <= 1.02 * min(np.median(err_i), np.median(err_c)), (np.median(err_v), np.median(err_i))
    # the same pose wherever image mode fits better: knees within 8 degrees (the target). Frames whose
    # 2D errors tie within 5 % are left out: there the landmarks cannot tell two depth hypotheses apart
    # (measured at 30 fps: 4.3 against 4.3 px and 11.3 against 11.6 px, where the knees differ by 11-14)
    clearly = err_i < 0.95 * err_v
    off = np.flatnonzero(clearly & (np.abs(knee_v - knee_i) > 8.0))
    assert len(off) == 0, [(i, round(knee_i[i], 1), round(knee_v[i], 1), err_i[i], err_v[i]) for i in off]


def test_a_repeated_frame_changes_nothing_at_any_rate(squat):
    """The prior is in time units, so showing a frame again a moment later (a replay at a higher rate) is
    fitted to the same pose: the knees of every repeat equal the first fit of that frame within 5 degrees (the
    refit may settle the weakly observed depth of a nearly straight limb a little differently — up to 2.5
    degrees measured; a prior counted per frame instead of per second would pull by tens of degrees)."""
    fitter = Fitter(FitConfig(body_height_m=1.65))
    fitter.fit(squat[0], 0, -0.2, (720, 1280), mode="video")  # the first frame of a video is fitted in image mode
    for i, lm in enumerate(squat):
        first = fitter.fit(lm, 2 * i, i / 5.0, (720, 1280), mode="video")
        again = fitter.fit(lm, 2 * i + 1, i / 5.0 + 1 / 30, (720, 1280), mode="video")
        assert first.ok and again.ok
        for knee in ("theta_kn_l", "theta_kn_r"):
            assert abs(first.variables[knee] - again.variables[knee]) < 5.0, (i, knee)
