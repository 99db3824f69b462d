"""The floor plane from the depth image through ``posed run``, real processes end to end (issue 33 item 1a): a
RealSense recording of a furnished room with no person in it (tests/daemon/depth_room.py: colour, depth 15 mm
beside it, with or without an accelerometer; made with pyrealsense2's software device and recorder as the IMU
and depth tests make theirs) -> capture (depth into the ring) -> landmark stage (the floor fitted about once a
second, on the frame as ``floor``) -> the landmarks topic carries it, and the fall detector's camera geometry
in the status comes from it: camera height within 5 cm and tilt and roll within 2 deg of the truth, from a
depth image within 2 s of the start, with the evidence (inliers, their fraction, residual, age)."""

from __future__ import annotations

import pytest

from tests.daemon.depth_room import Mount, write_db3
from tests.daemon.replay_util import replay_to_end

FPS, FRAMES = 15.0, 45            # 3 s of capture time
HEIGHT_TOL_M, ANGLE_TOL_DEG, WITHIN_S = 0.05, 2.0, 2.0


@pytest.mark.timeout(300)
@pytest.mark.parametrize("mount,accel_hz,gravity_from", [
    (Mount(1.25, 28.0, -2.5), 100.0, "imu"),       # a D435i on a robot's head: the IMU is the fit's prior
    (Mount(0.85, 12.0, 3.0), None, "depth"),       # a D435 (no accelerometer): tilt and roll from the floor
])
def test_the_floor_in_the_depth_image_gives_the_detector_its_geometry(tmp_path, mount, accel_hz, gravity_from):
    scene = write_db3(tmp_path / "room.db3", mount, FRAMES, FPS, accel_hz=accel_hz)
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    got = replay_to_end(run_dir, scene, "floor", ("landmarks", "status"), "pipeline.status_period_s=0.1",
                        "zenoh.publish_landmarks=true")
    msgs = sorted(got["landmarks"], key=lambda m: m["seq"])
    assert len(msgs) >= 25                          # pipeline.target_fps (10) thins the 15 fps
    assert all(m["landmarks"] is None for m in msgs)                     # nobody in the room
    t0 = msgs[0]["t"]
    planes = [m for m in msgs if "down" in (m.get("floor") or {})]
    assert planes, f"no frame carried a floor plane: {[m.get('floor') for m in msgs[:3]]}"
    first = planes[0]
    assert first["t"] - first["floor"]["age_s"] - t0 <= WITHIN_S        # measured in a depth image within 2 s
    fits = {m["floor"]["tries"] for m in planes}
    assert len(fits) >= 3                                                # refreshed about once a second ...
    assert max(m["floor"]["age_s"] for m in planes) <= 1.0 + 1.5 / FPS   # ... and never older than that
    for m in planes:
        f = m["floor"]
        assert f["height_m"] == pytest.approx(mount.height_m, abs=HEIGHT_TOL_M)
        assert f["tilt_deg"] == pytest.approx(mount.tilt_deg, abs=ANGLE_TOL_DEG)
        assert f["roll_deg"] == pytest.approx(mount.roll_deg, abs=ANGLE_TOL_DEG)
        assert f["prior"] in (("imu", "none") if accel_hz else ("none",))
    if accel_hz:    # the first depth frame may come before the accelerometer's first reading: fitted again then
        assert [m["floor"]["prior"] for m in planes[2:]] == ["imu"] * (len(planes) - 2)
        assert f["inliers"] > 500 and 0.1 < f["fraction"] <= 1.0 and f["rms_m"] < 0.03

    geos = [s["falls"]["geometry"] for s in got["status"]
            if s.get("falls", {}).get("geometry", {}).get("height_from") == "depth"]
    assert geos, f"no status with the depth floor: {[s.get('falls') for s in got['status'][-2:]]}"
    geo = geos[-1]
    assert geo["tilt_from"] == geo["roll_from"] == gravity_from
    assert geo["floor_below_camera_m"] == pytest.approx(mount.height_m, abs=HEIGHT_TOL_M)
    assert geo["tilt_deg"] == pytest.approx(mount.tilt_deg, abs=ANGLE_TOL_DEG)
    assert geo["roll_deg"] == pytest.approx(mount.roll_deg, abs=ANGLE_TOL_DEG)
    evidence = geo["depth_floor"]
    assert evidence["height_m"] == pytest.approx(mount.height_m, abs=HEIGHT_TOL_M)
    assert evidence["inliers"] > 500 and evidence["fraction"] > 0.1 and evidence["rms_m"] < 0.03
    assert 0.0 <= evidence["age_s"] <= 1.2 and evidence["tries"] >= 3 and evidence["misses"] == 0
    assert 0.0 < evidence["fit_ms"] < 50.0
