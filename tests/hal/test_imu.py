"""Gravity from a RealSense accelerometer (hal.imu): the filter against a plain reference, a recording with an
accelerometer stream played through the RealSense source, the live motion sensor's callback on a software
device, and ``posed record`` keeping the gravity."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from posed import hal
from posed.hal.imu import G_M_S2, MIN_SAMPLES, GravityEstimate, find_accel, rotation_of, sample_sink
from tests.hal.conftest import ACCEL_HZ, IMU_FRAMES, imu_down

# the recorded samples have 0.05 m/s^2 of noise per axis: averaged over ~50 samples (0.5 s) the direction
# is within atan(0.05 / 9.8 / sqrt(50) * 3) = 0.12 deg (3 sigma); 0.5 deg leaves room for the start-up
ANGLE_TOL_DEG = 0.5


def angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


def reference(samples, t_query, rotation, tau, tol, min_samples):
    """A plain re-statement of the accelerometer-only filter: samples in time order up to t_query, skip |a| far
    from g, down = -R a, exponential average with weight 1 - exp(-dt / tau), normalized (the gyro filter's
    reference, tests/hal/test_imu_gyro.py, without gyro samples)."""
    from tests.hal.test_imu_gyro import reference as with_gyro

    return with_gyro(samples, [], t_query, rotation, tau, tol, min_samples)


def test_filter_matches_the_reference_and_skips_bumps():
    rng = np.random.default_rng(3)
    rot = rotation_of(type("E", (), {"rotation": [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0]})())
    samples = []
    for n in range(300):
        t = n / 63.0 + rng.uniform(0, 0.002)
        tilt = 10.0 + 20.0 * (n > 150)                     # the robot tilts its head half way through
        a = -G_M_S2 * imu_down(tilt, 2.0) + rng.normal(0, 0.05, 3)
        if n % 23 == 0:
            a = a * 1.6                                   # a bump
        samples.append((t, a))
    est = GravityEstimate(rot, time_constant_s=0.3, tolerance=0.2, min_samples=MIN_SAMPLES)
    for t, a in samples:
        est.add(t, *a)
    for t_query in (0.05, 0.5, 2.0, 2.5, 3.0, 4.9):
        got = est.at(t_query)
        want = reference(samples, t_query, rot, 0.3, 0.2, MIN_SAMPLES)
        if want is None:
            assert got is None
        else:
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert est.counters()["imu_rejected"] == sum(1 for n in range(300) if n % 23 == 0)
    # after the tilt change (at 2.4 s) the estimate follows within a few time constants
    assert angle_deg(est.at(10.0), rot @ imu_down(30.0, 2.0)) < 0.5


def test_only_samples_up_to_the_frame_time_count():
    est = GravityEstimate(min_samples=1)
    for n in range(20):
        est.add(n * 0.01, 0.0, -G_M_S2, 0.0)          # level: down is +y
    for n in range(20, 40):
        est.add(n * 0.01, 0.0, 0.0, -G_M_S2)          # looking straight down: down is +z
    early = est.at(0.19)
    assert angle_deg(early, (0, 1, 0)) < 1e-9          # the later samples wait for a later frame
    assert angle_deg(est.at(0.39), (0, 0, 1)) < angle_deg(early, (0, 0, 1))


def test_no_estimate_before_enough_samples_and_bad_samples_are_counted():
    est = GravityEstimate()
    est.add(0.0, float("nan"), 0.0, 0.0)
    est.add(0.01, 0.0, 0.0, 0.0)                       # free fall or a dead sensor: not gravity
    for n in range(MIN_SAMPLES - 1):
        est.add(0.02 + n * 0.01, 0.0, -G_M_S2, 0.0)
    assert est.at(1.0) is None
    est.add(1.0, 0.0, -G_M_S2, 0.0)
    assert est.at(1.0) == pytest.approx((0.0, 1.0, 0.0))
    assert est.counters() == {"imu_samples": MIN_SAMPLES, "imu_rejected": 2}
    with pytest.raises(ValueError, match="3 x 3"):
        GravityEstimate(np.eye(2))


def _gravities(path, **cfg) -> tuple[list, dict]:
    out = []
    src = hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False, **cfg))
    with src:
        while True:
            try:
                out.append(src.read(5.0).gravity)
            except hal.EndOfStream:
                return out, dict(src.info)


def test_recording_with_an_accelerometer_gives_every_frame_its_gravity(squat_imu_db3):
    gravities, info = _gravities(squat_imu_db3.path)
    assert len(gravities) == IMU_FRAMES
    assert info["imu"] == "streaming" and info["imu_samples"] > 0.9 * ACCEL_HZ * (IMU_FRAMES - 1) / 5.0
    assert info["imu_rejected"] >= 1                                    # the bumps
    assert gravities[0] is None or angle_deg(gravities[0], imu_down()) < 2.0  # few samples before frame 0
    for g in gravities[1:]:
        assert g is not None and abs(np.linalg.norm(g) - 1.0) < 1e-9
        assert angle_deg(g, imu_down()) < ANGLE_TOL_DEG
    again, _ = _gravities(squat_imu_db3.path)
    assert again == gravities                                           # the same on every replay


def test_imu_off_and_recordings_without_an_accelerometer(squat_imu_db3, squat_db3):
    gravities, info = _gravities(squat_imu_db3.path, imu=False)
    assert info["imu"] == "off" and all(g is None for g in gravities)
    gravities, info = _gravities(squat_db3.path)
    assert info["imu"] == "none" and all(g is None for g in gravities)


def test_live_motion_sensor_callback_feeds_the_filter():
    """The live path's pieces on a software device (no camera here): the accelerometer is found among the
    device's sensors, opened and started with the sample callback; the samples it delivers reach the filter."""
    import pyrealsense2 as rs

    dev = rs.software_device()
    dev.add_sensor("Color")
    ms = dev.add_sensor("Motion Module")
    profiles = []
    for fps in (250, 63):
        m = rs.motion_stream()
        m.type, m.index, m.uid, m.fps, m.fmt = rs.stream.accel, 0, 10 + fps, fps, rs.format.motion_xyz32f
        m.intrinsics = rs.motion_device_intrinsic()
        profiles.append(ms.add_motion_stream(m))
    sensor, profile = find_accel(rs, dev)
    assert profile.fps() == 63                                          # the lowest rate
    est = GravityEstimate()
    sensor.open(profile)
    sensor.start(sample_sink(rs, est))
    try:
        down = imu_down(35.0, 4.0)
        for n in range(30):
            v = rs.vector()
            v.x, v.y, v.z = (float(c) for c in -G_M_S2 * down)
            f = rs.software_motion_frame()
            f.data, f.timestamp, f.frame_number = v, 1000.0 + n * 16.0, n
            f.domain = rs.timestamp_domain.hardware_clock
            f.profile = profiles[1].as_motion_stream_profile()
            ms.on_motion_frame(f)
        deadline = time.monotonic() + 5.0
        while est.counters()["imu_samples"] < 30 and time.monotonic() < deadline:
            est.at(math.inf)
            time.sleep(0.01)
        assert angle_deg(est.at(math.inf), down) < 1e-5
    finally:
        sensor.stop()
        sensor.close()
    no_imu = rs.software_device()
    no_imu.add_sensor("Color")
    assert find_accel(rs, no_imu) is None


def test_record_keeps_the_gravity(tmp_path, squat_imu_db3):
    out = tmp_path / "again.db3"
    with hal.open_source(hal.SourceConfig(type="file", path=str(squat_imu_db3.path), realtime=False)) as src:
        summary = hal.record(src, str(out))
    assert summary.frames == IMU_FRAMES
    gravities, info = _gravities(out)
    assert info["imu"] == "streaming"
    # one (already filtered) sample per frame: the estimate starts after MIN_SAMPLES frames, then agrees
    assert all(g is None for g in gravities[:MIN_SAMPLES - 1])
    for g in gravities[MIN_SAMPLES:]:
        assert angle_deg(g, imu_down()) < ANGLE_TOL_DEG
