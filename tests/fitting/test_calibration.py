"""Per-user link lengths (paper section 3, step 1) and the calibration file."""

from dataclasses import asdict, replace

import numpy as np
import pytest
import yaml

from posed.bench import simulate as S
from posed.fitting.body import BodyDimensions, CalibrationError, read_calibration, write_calibration
from posed.fitting.calibration import CalibrationFailed, calibrate
from posed.fitting.config import FitConfig
from posed.fitting.fitter import Fitter


def standing_frames(dims, n=12, noise=1.0, yaw=0.0):
    # arms hanging straight (the measurement sees the elbow's bend as a shorter forearm)
    pose = S.STANDING.replace(psi_bd=yaw, theta_sh_l=0, theta_sh_r=0, theta_el_l=2, theta_el_r=2)
    return [S.render(pose, dims=dims, noise_px=noise, seed=i) for i in range(n)]


def test_calibration_recovers_a_persons_proportions():
    # a person with longer legs and shorter arms than the table
    true = replace(BodyDimensions.from_height(1.80), thigh_m=0.47, shank_m=0.45, upper_arm_m=0.31,
                   shoulder_half_m=0.20)
    rep = calibrate(standing_frames(true), 1.80)
    assert rep.frames_used == 12
    for key in ("trunk_m", "shoulder_half_m", "hip_half_m", "upper_arm_m", "forearm_m", "thigh_m", "shank_m"):
        assert getattr(rep.dims, key) == pytest.approx(getattr(true, key), rel=0.03), key


def test_calibration_needs_ten_standing_frames():
    dims = BodyDimensions.from_height(1.6)
    frames = standing_frames(dims, n=6) + [S.render(S.pose("sit_chair", 0.0), dims=dims)] * 8 + [None]
    with pytest.raises(CalibrationFailed, match="only 6 of 15 frames") as err:
        calibrate(frames, 1.6)
    assert "not standing" in str(err.value) and "no person" in str(err.value)
    with pytest.raises(CalibrationFailed, match="not facing"):
        calibrate(standing_frames(dims, yaw=70.0), 1.6)


def test_calibration_file_round_trip_is_yaml_and_used_by_the_fit(tmp_path):
    dims = replace(BodyDimensions.from_height(1.7), thigh_m=0.44)
    path = tmp_path / "user.yaml"
    write_calibration(path, dims, frames=12, source='rec "a".landmarks.jsonl')
    back = read_calibration(path)
    for k, v in asdict(dims).items():
        assert getattr(back, k) == pytest.approx(v, abs=1e-4)
    parsed = yaml.safe_load(path.read_text())
    assert parsed["format"] == "posed.calibration" and parsed["thigh_m"] == pytest.approx(0.44)
    assert parsed["source"] == 'rec "a".landmarks.jsonl'
    fitter = Fitter(FitConfig(calibration=str(path)))
    assert fitter.dims.thigh_m == pytest.approx(0.44, abs=1e-4)
    # the fit with the right lengths recovers a pose of this person exactly
    pose = S.pose("walk_left_forward", 30.0)
    r = fitter.fit(S.render(pose, dims=back), 0, 0.0, (640, 480), mode="image")
    assert r.ok and abs(r.variables["theta_kn_r"] - 15.0) < 0.5


@pytest.mark.parametrize(("text", "match"), [
    ("format: other\nversion: 1\n", "format is 'other'"),
    ("format: posed.calibration\nversion: 2\n", "version '2' is not supported"),
    ("format: posed.calibration\nversion: 1\n", "is missing"),
    ("format: posed.calibration\n  nested: 1\n", "expected 'key: value'"),
])
def test_bad_calibration_files(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(CalibrationError, match=match):
        read_calibration(path)
    with pytest.raises(CalibrationError, match="posed calibrate"):
        read_calibration(tmp_path / "missing.yaml")


def test_implausible_length_rejected(tmp_path):
    path = tmp_path / "user.yaml"
    write_calibration(path, BodyDimensions.from_height(1.7), frames=10)
    text = path.read_text().replace("thigh_m: 0.4165", "thigh_m: -1")
    path.write_text(text)
    with pytest.raises(CalibrationError, match="thigh_m"):
        read_calibration(path)
    assert np.isfinite(BodyDimensions.from_height(1.7).leg_m)


def test_huge_or_binary_calibration_files_are_clear_errors(tmp_path):
    """Read with a bound: /dev/zero or a huge file is an error naming the size, binary data one naming the byte."""
    from posed.fitting import CalibrationError, read_calibration

    with pytest.raises(CalibrationError, match="larger than 65536 bytes"):
        read_calibration("/dev/zero")
    binary = tmp_path / "cal.yaml"
    binary.write_bytes(b"format: x\n\xff\xfe")
    with pytest.raises(CalibrationError, match="not UTF-8"):
        read_calibration(binary)
