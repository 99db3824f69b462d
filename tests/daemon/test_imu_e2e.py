"""The RealSense accelerometer's gravity through ``posed run``, real processes end to end: a recording with an
accelerometer stream (the real squat video's colour, a camera tilted 20 deg down and rolled -3 deg) -> capture
(gravity on the FrameRef) -> landmark stage (on the frame) -> the landmarks topic carries it, and the fall
detector's camera geometry in the status comes from the IMU. ``posed landmarks`` writes the same gravity into
a recording, and a replay of that recording gives the detector the same geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.cli import main
from posed.client import contract
from posed.landmarks import read_recording
from tests.daemon.replay_util import replay_to_end
from tests.hal.conftest import IMU_FRAMES, IMU_ROLL_DEG, IMU_TILT_DEG, imu_down

ANGLE_TOL_DEG = 0.5   # as tests/hal/test_imu.py: 3-sigma noise of the average is 0.12 deg


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


def _run(tmp_path, source, robot: str) -> tuple[list[dict], list[dict], list[dict]]:
    """The landmarks messages by seq, the status messages (every 0.1 s) in arrival order and the poses."""
    got = replay_to_end(tmp_path, source, robot, ("landmarks", "status", "pose"), "pipeline.status_period_s=0.1",
                        "zenoh.publish_landmarks=true")
    return sorted(got["landmarks"], key=lambda m: m["seq"]), got["status"], got["pose"]


def _fitted_with_gravity(poses: list[dict], landmarks: list[dict]) -> None:
    """Every fitted frame whose landmarks carried gravity was fitted with it (fitting.vertical), the others
    not."""
    carried = {m["seq"] for m in landmarks if "gravity" in m}
    fitted = [p for p in poses if p["ok"]]
    assert len(fitted) >= IMU_FRAMES - 2, [p.get("reason") for p in poses if not p["ok"]]
    for p in fitted:
        assert p.get("vertical") == ("gravity" if p["seq"] in carried else None), p["seq"]
        assert contract.errors(p) == [], p["seq"]        # vertical and down follow the shipped schema


def _imu_geometry(statuses: list[dict]) -> dict:
    found = [s["falls"]["geometry"] for s in statuses
             if s.get("falls", {}).get("geometry", {}).get("tilt_from") == "imu"]
    assert found, f"no status with the IMU's geometry among {len(statuses)}: " \
                  f"{[s.get('falls') for s in statuses[-3:]]}"
    return found[-1]


@pytest.mark.timeout(300)
def test_accelerometer_gravity_reaches_the_topic_and_the_fall_detector(tmp_path, squat_imu_db3, capsys):
    run_dir = tmp_path / "db3"
    run_dir.mkdir()
    msgs, statuses, poses = _run(run_dir, squat_imu_db3.path, "imu")
    assert [m["seq"] for m in msgs] == list(range(IMU_FRAMES))
    with_gravity = [m for m in msgs if "gravity" in m]
    assert len(with_gravity) >= IMU_FRAMES - 1                          # all but possibly the first frame
    for m in with_gravity:
        assert _angle(m["gravity"], imu_down()) < ANGLE_TOL_DEG
    geo = _imu_geometry(statuses)
    assert geo["roll_from"] == "imu"
    assert geo["tilt_deg"] == pytest.approx(IMU_TILT_DEG, abs=ANGLE_TOL_DEG)
    assert geo["roll_deg"] == pytest.approx(IMU_ROLL_DEG, abs=ANGLE_TOL_DEG)
    _fitted_with_gravity(poses, msgs)

    # posed landmarks writes the gravity into the recording; its replay gives the detector the same geometry
    recording = tmp_path / "squat_imu.landmarks.jsonl"
    assert main(["landmarks", str(squat_imu_db3.path), "-o", str(recording)]) == 0
    capsys.readouterr()
    _, frames, _ = read_recording(recording)
    by_seq = {m["seq"]: m for m in with_gravity}
    assert sum(f.gravity is not None for f in frames) >= IMU_FRAMES - 1
    for f in frames:
        if f.gravity is not None and f.seq in by_seq:
            assert _angle(f.gravity, by_seq[f.seq]["gravity"]) < 0.05
    run_dir = tmp_path / "jsonl"
    run_dir.mkdir()
    replayed, statuses, poses = _run(run_dir, recording, "replay")
    assert [m.get("gravity") for m in replayed] == [None if f.gravity is None else list(f.gravity) for f in frames]
    geo = _imu_geometry(statuses)
    assert geo["tilt_deg"] == pytest.approx(IMU_TILT_DEG, abs=ANGLE_TOL_DEG)
    _fitted_with_gravity(poses, replayed)

