"""fitting.measured: the one rule for what a frame measured (landmarks, joint angles, joint positions), the
``measured`` field the fit writes, and the plain angle names ``FitResult.angle`` takes."""

import json

import numpy as np
import pytest

from posed import fitting
from posed.fitting import (
    ANGLE_NEEDS,
    BODY_LANDMARK_NAMES,
    BODY_LANDMARKS,
    FIXED_ANGLE_NAMES,
    JOINT_ANGLE_NAMES,
    FitResult,
    Measured,
    measured_landmarks,
)
from posed.landmarks import read_recording


def _frame(vis=0.9, presence=0.9):
    lm = np.zeros((33, 5))
    lm[:, 0], lm[:, 1] = np.arange(33) * 3.0, 100.0
    lm[:, 3], lm[:, 4] = vis, presence
    return lm


def test_a_landmark_is_measured_when_finite_visible_and_present():
    lm = _frame()
    assert measured_landmarks(lm) == BODY_LANDMARK_NAMES
    lm[13, 3] = 0.29                     # left elbow: visibility below the fit's visibility_drop
    lm[14, 4] = 0.1                      # right elbow: visible enough, but hardly present in the image
    lm[15, :2] = np.nan                  # left wrist: unknown
    lm[16, 4] = np.nan                   # right wrist: no presence given: visibility decides
    got = measured_landmarks(lm)
    assert "left_elbow" not in got and "right_elbow" not in got and "left_wrist" not in got
    assert "right_wrist" in got and len(got) == 9
    assert measured_landmarks(lm, visibility_drop=0.05) == tuple(n for n in BODY_LANDMARK_NAMES
                                                                 if n not in ("left_wrist",))
    assert measured_landmarks(None) == ()
    with pytest.raises(ValueError, match="33 rows"):
        measured_landmarks(np.zeros((12, 5)))


def test_the_table_covers_every_estimated_angle_and_never_a_fixed_one():
    from posed.fitting.reported import FIXED_NAMES

    assert set(FIXED_ANGLE_NAMES) == set(FIXED_NAMES)
    estimated = set(JOINT_ANGLE_NAMES) - set(FIXED_NAMES)
    assert set(ANGLE_NEEDS) == estimated | {"theta_bd", "phi_bd", "psi_bd"}
    from posed.fitting.measured import BODY_LANDMARK_INDEX
    assert tuple(BODY_LANDMARK_INDEX.values()) == BODY_LANDMARKS
    everything = Measured.from_landmarks(BODY_LANDMARK_NAMES)
    assert set(everything.angles) == set(ANGLE_NEEDS) and not set(everything.angles) & set(FIXED_ANGLE_NAMES)


def test_an_angle_needs_both_of_its_segments():
    seen = set(BODY_LANDMARK_NAMES) - {"left_elbow"}
    m = Measured.from_landmarks(seen)
    # the left elbow places the upper arm (shoulder angles) and the forearm (elbow angle)
    assert not {"theta_sh_l", "phi_sh_l", "theta_el_l"} & set(m.angles)
    assert {"theta_sh_r", "theta_el_r", "theta_kn_l", "theta_tr", "theta_bd"} <= set(m.angles)
    assert "left_elbow" not in m.joints and "left_wrist" in m.joints
    m = Measured.from_landmarks(set(BODY_LANDMARK_NAMES) - {"right_shoulder"})
    # one torso landmark gone: trunk and pelvis are the model's guess, and every angle measured from them
    assert set(m.angles) == {"theta_el_l", "theta_kn_l", "theta_kn_r"}
    assert "mid_hip" in m.joints
    assert "mid_hip" not in Measured.from_landmarks(set(BODY_LANDMARK_NAMES) - {"left_hip"}).joints


def test_the_result_gives_only_measured_values_and_takes_plain_names():
    r = FitResult(3, 0.1, True, variables={"theta_bd": 4.0, "theta_el_l": 50.0},
                  joint_angles_deg={"theta_kn_l": 30.0, "theta_el_l": 50.0, "theta_hd": 0.0},
                  joints_3d={"mid_hip": (0, 0, 0), "left_wrist": (0.1, 0.2, 0.3), "left_knee": (0, 0.4, 0)},
                  measured=Measured.from_landmarks(set(BODY_LANDMARK_NAMES) - {"left_wrist"}))
    assert r.angle("left knee flexion") == 30.0 == r.angle("theta_kn_l") == r.angle("Left Knee Flexion")
    assert r.angle("left elbow flexion") is None         # its wrist was not measured
    assert r.angle("head flexion") is None               # held fixed by the model: never measured
    assert r.measured_angles(plain=True) == {"left knee flexion": 30.0, "body pitch": 4.0}
    assert set(r.measured_joints()) == {"mid_hip", "left_knee"}
    with pytest.raises(KeyError, match="left knee flexion"):
        r.angle("left knee")
    back = FitResult.from_json(json.loads(json.dumps(r.to_json())))
    assert back == r and back.to_json()["measured"]["angles"] == list(r.measured.angles)
    assert FitResult.failure(4, 0.2, "no person").measured == Measured()
    assert "measured" not in FitResult.failure(4, 0.2, "no person").to_json()


def test_a_result_written_before_the_field_is_judged_by_the_same_rule():
    old = {"seq": 0, "t": 0.0, "ok": True, "joint_angles_deg": {"theta_kn_r": 12.0, "theta_sh_l": 3.0},
           "missing": ["right_ankle", "left_elbow"], "unobserved": ["theta_kn_r", "theta_sh_l", "phi_sh_l"]}
    r = FitResult.from_json(old)
    assert r.measured == Measured.from_landmarks(set(BODY_LANDMARK_NAMES) - {"right_ankle", "left_elbow"})
    assert r.angle("right knee flexion") is None and r.angle("left shoulder flexion") is None
    with pytest.raises(ValueError, match="unknown name"):
        FitResult.from_json({**old, "measured": {"landmarks": [], "angles": ["theta_knee"], "joints_3d": []}})


def test_the_fit_writes_what_a_real_recording_measured(shared_data):
    """urfd_04: MediaPipe Holistic gave no elbows, and during the fall one shoulder at a time is lost: the
    fit still runs then, but the trunk and body angles it reports are the model's guess."""
    header, frames, _ = read_recording(shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl")
    fitter = fitting.Fitter(fitting.FitConfig())
    ok = []
    for f in frames:
        r = fitter.fit(f.landmarks, f.seq, f.t, header.image_size, intrinsics=header.camera)
        if r.ok:
            ok.append((f, r))
    assert len(ok) > 100
    for f, r in ok:
        seen = set(measured_landmarks(f.landmarks))
        assert set(r.measured.landmarks) == seen
        assert not {"theta_el_l", "theta_el_r", "theta_sh_l", "theta_sh_r"} & set(r.measured.angles)
        assert "left_elbow" not in r.measured_joints() and "left_elbow" in r.joints_3d
        torso = {"left_shoulder", "right_shoulder", "left_hip", "right_hip"} <= seen
        assert torso == (r.angle("body pitch") is not None)
        clamped = "theta_tr" in r.extra.get("at_limit", ())      # held at a joint limit: not a measurement
        assert ("theta_tr" in r.measured.angles) == (torso and not clamped)
    assert any(not {"left_shoulder", "right_shoulder"} <= set(r.measured.landmarks) for _, r in ok)
