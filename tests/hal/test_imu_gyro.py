"""The accelerometer + gyroscope filter of hal.imu: the propagation against a plain matrix exponential, a camera
turning at a constant rate followed without lag (the accelerometer-only filter lags it by about rate * tau),
a gyro bias bounded by the accelerometer's pull as a first-order loop predicts, the filter against a plain
re-statement on jittered samples, the time semantics, and the gyro stream through a recording and a software
device's motion sensor."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from posed import hal
from posed.hal.imu import (
    G_M_S2,
    GYRO_MAX_GAP_S,
    MIN_SAMPLES,
    TIME_CONSTANT_S,
    GravityEstimate,
    find_accel,
    find_gyro,
    propagate,
    rotation_of,
    sample_sink,
)
from tests.hal.conftest import COLOUR_K, SQUAT_FPS, TS0_MS, colour_frames


def angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


def skew(w) -> np.ndarray:
    x, y, z = w
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def expm(a: np.ndarray, terms: int = 40) -> np.ndarray:
    """exp(a) by its Taylor series (plain NumPy; exact to rounding for the angles used here, under 2 rad)."""
    out, term = np.eye(3), np.eye(3)
    for n in range(1, terms):
        term = term @ a / n
        out = out + term
    return out


def turned_down(d0, omega, t) -> np.ndarray:
    """A room-fixed direction seen from a camera turning at the constant rate omega (camera axes) since t = 0:
    dv/dt = -omega x v, so v(t) = exp(-[omega]x t) v(0)."""
    return expm(-skew(omega) * t) @ np.asarray(d0, float)


def test_propagation_is_the_rotation_of_dv_dt_equal_minus_omega_cross_v():
    rng = np.random.default_rng(11)
    for _ in range(50):
        v = rng.normal(size=3)
        w = rng.normal(size=3) * rng.uniform(0.01, 3.0)
        dt = rng.uniform(0.001, 0.5)
        np.testing.assert_allclose(propagate(v, w, dt), turned_down(v, w, dt), rtol=0, atol=1e-12)
    v = np.array([0.0, 1.0, 0.0])
    assert np.array_equal(propagate(v, np.zeros(3), 0.01), v)
    # the sign, plainly: a camera tilting down turns about -x (forward towards image-down), and the down it
    # sees moves towards +z (forward)
    assert propagate(v, np.array([-0.1, 0.0, 0.0]), 1.0)[2] == pytest.approx(math.sin(0.1))


def _constant_rate(est_gyro: GravityEstimate | None, est_accel: GravityEstimate, omega, d0, seconds: float,
                   gyro_hz: float = 200.0, every: int = 3):
    """Feed a camera turning at ``omega`` (rad/s, accel axes) from down ``d0``: gyro samples at ``gyro_hz``, an
    accelerometer sample (-g down, no noise) on every ``every``-th gyro tick; the queried times are the
    accelerometer's."""
    times = []
    for n in range(int(seconds * gyro_hz) + 1):
        t = n / gyro_hz
        if est_gyro is not None:
            est_gyro.add_gyro(t, *omega)
        if n % every == 0:
            a = -G_M_S2 * turned_down(d0, omega, t)
            if est_gyro is not None:
                est_gyro.add(t, *a)
            est_accel.add(t, *a)
            times.append(t)
    return times


def test_a_camera_turning_at_a_constant_rate_is_followed_without_lag():
    """A noiseless gyro and accelerometer consistent with a constant turn (30 deg/s about an oblique axis, in
    the accelerometer's axes, the colour camera's rotated by a quarter turn): after the first gyro sample the
    average is turned exactly with the camera, so every pull of the accelerometer is along it, and the estimate
    is the analytic down to rounding. The accelerometer-only filter on the same samples lags by about
    rate * tau (first-order low-pass of a ramp): 15 deg at 30 deg/s and 0.5 s; over 10 deg is asserted."""
    rot = rotation_of(type("E", (), {"rotation": [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0]})())
    axis = np.array([1.0, 0.3, -0.5])
    omega = math.radians(30.0) * axis / np.linalg.norm(axis)
    d0 = np.array([0.1, 0.95, 0.3]) / np.linalg.norm([0.1, 0.95, 0.3])
    est, acc = GravityEstimate(rot), GravityEstimate(rot)
    times = _constant_rate(est, acc, omega, d0, 4.0)
    checked = 0
    for t in times[MIN_SAMPLES:]:
        want = rot @ turned_down(d0, omega, t)
        got = est.at(t)
        assert angle_deg(got, want) < 1e-6, t
        if t > 2.0:
            assert angle_deg(acc.at(t), want) > 10.0, t
            checked += 1
    assert checked > 100
    est.at(math.inf)
    assert est.counters() == {"imu_samples": len(times), "imu_rejected": 0, "imu_gyro_samples": 801,
                              "imu_gyro_rejected": 0}


def _still_with_bias(down, bias, seconds, gyro_hz=200.0, every=3) -> tuple[GravityEstimate, float]:
    """A still camera (accelerometer: -g down, no noise, on every ``every``-th gyro tick) whose gyro reads the
    constant ``bias``; the estimate and the last accelerometer sample's time."""
    est = GravityEstimate()
    t = 0.0
    for n in range(int(seconds * gyro_hz) + 1):
        t = n / gyro_hz
        est.add_gyro(t, *bias)
        if n % every == 0:
            est.add(t, *(-G_M_S2 * down))
            t_last = t
    return est, t_last


def test_a_gyro_bias_on_a_still_camera_is_bounded_by_the_accelerometer_s_pull():
    """A still camera whose gyro reads a constant bias b perpendicular to down: between two accelerometer
    samples (period T) the average turns by phi = |b| T, then moves by alpha = 1 - exp(-T / tau) towards the
    true down. In the plane of the turn (complex z, the true down along the real axis) that is
    z <- (1 - alpha) z e^(i phi) + alpha g, whose fixed point's angle is
    atan((1 - alpha) sin phi / (1 - (1 - alpha) cos phi)), approached as (1 - alpha)^n. Its first order is
    |b| tau, the steady state of the continuous loop e' = |b| - e / tau, and it is below it since
    (1 - alpha) / alpha = 1 / (e^(T/tau) - 1) < tau / T: the drift is bounded by bias * tau (0.5 deg for the
    BMI055's typical 1 deg/s at tau 0.5 s). Without the accelerometer the same bias turns the estimate on
    without bound (|b| t). A bias about the down direction turns nothing."""
    down = np.array([0.0, math.cos(math.radians(20.0)), math.sin(math.radians(20.0))])
    b = math.radians(1.0)
    seconds = 24 * TIME_CONSTANT_S                                       # (1 - alpha)^n ~ e^-24 by then
    est, t_last = _still_with_bias(down, (b, 0.0, 0.0), seconds)
    period = 3 / 200.0
    phi, alpha = b * period, 1.0 - math.exp(-period / TIME_CONSTANT_S)
    fixed = math.degrees(math.atan((1 - alpha) * math.sin(phi) / (1 - (1 - alpha) * math.cos(phi))))
    got = angle_deg(est.at(t_last), down)
    assert got == pytest.approx(fixed, rel=1e-6)
    bound = math.degrees(b * TIME_CONSTANT_S)
    assert 0.9 * bound < got <= bound
    # between accelerometer samples it turns by at most phi more
    assert max(angle_deg(est.at(t_last + k / 200.0), down) for k in (1, 2)) <= bound + math.degrees(phi)
    # without the accelerometer's pull, the bias drifts on: 10 s more of gyro only, 10 deg more
    for n in range(1, 2001):
        est.add_gyro(t_last + 2 / 200.0 + n / 200.0, b, 0.0, 0.0)
    assert angle_deg(est.at(math.inf), down) == pytest.approx(got + math.degrees(phi) * 2 / 3 + 10.0, abs=1e-6)
    # about the down direction: no turn of down at all
    est, t_last = _still_with_bias(down, tuple(math.radians(0.7) * down), seconds)
    assert angle_deg(est.at(t_last), down) < 1e-6


def reference(accel, gyro, t_query, rotation, tau, tol, min_samples):
    """A plain re-statement of the filter: both sample lists merged in time order (a gyro sample before an
    accelerometer sample of the same stamp), up to t_query; a gyro sample turns the average by
    exp(-[R w]x dt) (dt since the previous gyro sample, not over GYRO_MAX_GAP_S); an accelerometer sample as the
    accelerometer-only filter (skip |a| far from g, exponential average of -R a)."""
    events = sorted([(t, 0, w) for t, w in gyro] + [(t, 1, a) for t, a in accel], key=lambda e: (e[0], e[1]))
    mean, t_last, n, tg = None, None, 0, None
    for t, kind, x in events:
        if t > t_query:
            break
        x = np.asarray(x, float)
        if kind == 0:
            if tg is not None and mean is not None and 0 < t - tg <= GYRO_MAX_GAP_S:
                mean = expm(-skew(rotation @ x) * (t - tg)) @ mean
            tg = t if tg is None else max(tg, t)
            continue
        if abs(np.linalg.norm(x) - G_M_S2) > tol * G_M_S2:
            continue
        down = -(rotation @ x)
        if mean is None:
            mean = down
        else:
            dt = min(max(t - t_last, 0.0), 10 * tau)
            w = 1 - math.exp(-dt / tau) if dt > 0 else 1 / (n + 1)
            mean = mean + w * (down - mean)
        t_last = t if t_last is None else max(t_last, t)
        n += 1
    if mean is None or n < min_samples:
        return None
    return mean / np.linalg.norm(mean)


def test_filter_matches_the_reference_with_jitter_bumps_ties_and_a_gap():
    rng = np.random.default_rng(5)
    rot = rotation_of(type("E", (), {"rotation": [0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0]})())
    accel, gyro = [], []
    for n in range(250):
        t = n / 63.0 + rng.uniform(0, 0.002)
        a = -G_M_S2 * np.array([0.1, 0.9, 0.4]) / np.linalg.norm([0.1, 0.9, 0.4]) + rng.normal(0, 0.3, 3)
        if n % 19 == 0:
            a = a * 1.7                                                 # a bump
        accel.append((t, a))
    for n in range(800):
        t = n / 200.0 + rng.uniform(0, 0.001)
        if 1.5 < t < 1.8:
            continue                                                    # lost samples: a gap not integrated
        gyro.append((t, rng.normal(0, 0.5, 3)))
    gyro.append((accel[100][0], np.array([0.3, -0.2, 0.1])))            # a tie with an accelerometer sample
    gyro.sort(key=lambda s: s[0])
    est = GravityEstimate(rot, time_constant_s=0.4)
    for t, w in gyro:
        est.add_gyro(t, *w)
    for t, a in accel:
        est.add(t, *a)
    for t_query in (0.05, 0.5, accel[100][0], 1.6, 2.0, 2.5, 3.9):
        got = est.at(t_query)
        want = reference(accel, gyro, t_query, rot, 0.4, 0.2, MIN_SAMPLES)
        if want is None:
            assert got is None
        else:
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    est.at(math.inf)
    assert est.counters()["imu_gyro_samples"] == len(gyro)


def test_only_gyro_samples_up_to_the_frame_time_count_and_bad_ones_are_counted():
    est = GravityEstimate(min_samples=1)
    est.add(0.0, 0.0, -G_M_S2, 0.0)
    est.add_gyro(0.0, 0.0, 0.0, 0.0)
    for n in range(1, 21):
        est.add_gyro(n * 0.005, -1.0, 0.0, 0.0)                        # 1 rad/s down from 0.005 s on
    est.add_gyro(0.2, float("nan"), 0.0, 0.0)
    assert est.at(0.0) == pytest.approx((0.0, 1.0, 0.0))                # the later gyro samples wait
    got = est.at(0.05)                                                   # ten of them: 0.05 rad
    assert got == pytest.approx((0.0, math.cos(0.05), math.sin(0.05)), abs=1e-12)
    est.at(1.0)
    assert est.counters() == {"imu_samples": 1, "imu_rejected": 0, "imu_gyro_samples": 21,
                              "imu_gyro_rejected": 1}
    # a gyro sample before any accelerometer sample turns nothing (there is nothing to turn), nor gives a down
    est = GravityEstimate(min_samples=1)
    est.add_gyro(0.0, 1.0, 0.0, 0.0)
    est.add_gyro(0.005, 1.0, 0.0, 0.0)
    assert est.at(1.0) is None


# -- the gyro stream through a recording and a software device ------------------------------------------------

FRAMES = 12
ACCEL_HZ, GYRO_HZ = 63, 200
TURN_DEG_S = 20.0        # the camera tilts down at this rate for the whole recording, from 5 deg down


def tilt_at(t: float) -> float:
    return 5.0 + TURN_DEG_S * t


def _down(t: float) -> np.ndarray:
    a = math.radians(tilt_at(t))
    return np.array([0.0, math.cos(a), math.sin(a)])


def write_turning_db3(path, squat_frames, gyro: bool = True, frames: int = FRAMES):
    """Colour (the squat video at 5 fps) and a camera tilting down at TURN_DEG_S: accelerometer samples at
    ACCEL_HZ (-g down, no noise) and, with ``gyro``, gyro samples at GYRO_HZ (-TURN_DEG_S about x, rad/s);
    identity depth -> colour (colour only). Returns the frames' times in seconds from the first."""
    from posed.hal.db3 import Db3Writer

    colour, pts = colour_frames(squat_frames, 20, frames)
    with Db3Writer(path, COLOUR_K, SQUAT_FPS, accel_fps=ACCEL_HZ, gyro_fps=GYRO_HZ if gyro else None) as w:
        na = ng = 0
        for i, image in enumerate(colour):
            while ng * 1000.0 / GYRO_HZ <= pts[i] and gyro:
                w.write_gyro(TS0_MS + ng * 1000.0 / GYRO_HZ, (-math.radians(TURN_DEG_S), 0.0, 0.0))
                ng += 1
            while na * 1000.0 / ACCEL_HZ <= pts[i]:
                t = na / ACCEL_HZ
                w.write_accel(TS0_MS + na * 1000.0 / ACCEL_HZ, tuple(-G_M_S2 * _down(t)))
                na += 1
            w.write(image, None, TS0_MS + pts[i], i)
    return [p / 1000.0 for p in pts]


def _gravities(path) -> tuple[list, dict]:
    out = []
    with hal.open_source(hal.SourceConfig(type="file", path=str(path), realtime=False)) as src:
        while True:
            try:
                out.append(src.read(5.0).gravity)
            except hal.EndOfStream:
                return out, dict(src.info)


def test_a_recording_with_a_gyro_stream_follows_the_turn(tmp_path, squat_frames):
    """The written recording plays its gyro stream beside the accelerometer's: info says so, and every frame's
    gravity is the camera's true down (the accelerometer samples run 1/63 s behind at most, but the gyro's
    turn carries the average up to the frame: within a gyro period's turn, 0.1 deg). The same recording
    without the gyro stream plays as today (gyro none) and lags about rate * tau = 10 deg."""
    with_gyro = tmp_path / "turn_gyro.db3"
    times = write_turning_db3(with_gyro, squat_frames)
    gravities, info = _gravities(with_gyro)
    assert len(gravities) == FRAMES
    assert info["imu"] == "streaming" and info["gyro"] == "streaming"
    assert info["imu_gyro_samples"] >= int(times[-1] * GYRO_HZ)
    for t, g in zip(times[1:], gravities[1:], strict=True):
        assert g is not None and angle_deg(g, _down(t)) < 0.1, t
    without = tmp_path / "turn.db3"
    write_turning_db3(without, squat_frames, gyro=False)
    gravities, info = _gravities(without)
    assert info["imu"] == "streaming" and info["gyro"] == "none" and "imu_gyro_samples" not in info
    assert all(angle_deg(g, _down(t)) > 6.0 for t, g in zip(times, gravities, strict=True) if t >= 1.5)


def test_record_keeps_the_gyro_s_turn(tmp_path, squat_frames):
    """``posed record`` of a source whose gravity comes with a gyro writes the turn between frames as a gyro
    stream: its replay starts once MIN_SAMPLES frames have given their (one) accelerometer sample each, and
    then gives every frame the gravity the source gave it (the turn carries the average from one frame's down
    to the next exactly, so each pull is along it). Without the gyro stream the replay low-passes the recorded
    gravity again and lags the turn (about rate * tau, 10 deg)."""
    src_path = tmp_path / "turn.db3"
    times = write_turning_db3(src_path, squat_frames, frames=24)
    original, _ = _gravities(src_path)
    out = tmp_path / "again.db3"
    with hal.open_source(hal.SourceConfig(type="file", path=str(src_path), realtime=False)) as src:
        summary = hal.record(src, str(out))
    assert summary.frames == 24
    replayed, info = _gravities(out)
    assert info["gyro"] == "streaming"
    assert all(g is None for g in replayed[:MIN_SAMPLES])              # frame 0 had none: 10 samples by frame 10
    for t, a, b in list(zip(times, original, replayed, strict=True))[MIN_SAMPLES:]:
        assert angle_deg(a, b) < 1e-4, t                                 # float32 samples in the file
    # the source's info decides: without a gyro there, the recording has none (and lags on replay)
    from posed.hal import recorder

    class NoGyro:
        def __init__(self, src):
            self._src = src

        def __getattr__(self, name):
            return getattr(self._src, name)

        @property
        def info(self):
            return {**self._src.info, "gyro": "none"}

    out2 = tmp_path / "accel_only.db3"
    with hal.open_source(hal.SourceConfig(type="file", path=str(src_path), realtime=False)) as src:
        recorder.record(NoGyro(src), str(out2))
    lagged, info = _gravities(out2)
    assert info["gyro"] == "none"
    assert angle_deg(lagged[-1], original[-1]) > 6.0


def test_live_motion_sensor_with_a_gyro_feeds_both_streams():
    """The live path's pieces on a software device: the gyro is found on the accelerometer's motion sensor at
    its lowest rate, both profiles are opened together and started with the sample callback, and the gyro
    samples it delivers turn the filter's down."""
    import pyrealsense2 as rs

    dev = rs.software_device()
    dev.add_sensor("Color")
    ms = dev.add_sensor("Motion Module")
    profiles = {}
    for kind, fps in ((rs.stream.accel, 63), (rs.stream.gyro, 400), (rs.stream.gyro, 200)):
        m = rs.motion_stream()
        m.type, m.index, m.uid, m.fps, m.fmt = kind, 0, 10 + fps, fps, rs.format.motion_xyz32f
        m.intrinsics = rs.motion_device_intrinsic()
        profiles[fps] = ms.add_motion_stream(m)
    sensor, accel = find_accel(rs, dev)
    gyro = find_gyro(rs, sensor)
    assert accel.fps() == 63 and gyro is not None and gyro.fps() == 200
    est = GravityEstimate(min_samples=1)
    sensor.open([accel, gyro])
    sensor.start(sample_sink(rs, est))

    def send(profile, n, t_ms, xyz):
        v = rs.vector()
        v.x, v.y, v.z = (float(c) for c in xyz)
        f = rs.software_motion_frame()
        f.data, f.timestamp, f.frame_number = v, t_ms, n
        f.domain = rs.timestamp_domain.hardware_clock
        f.profile = profile.as_motion_stream_profile()
        ms.on_motion_frame(f)

    try:
        send(profiles[63], 0, 1000.0, (0.0, -G_M_S2, 0.0))                # level
        for n in range(21):                                               # then 0.1 s at -0.5 rad/s about x
            send(profiles[200], n, 1000.0 + 5.0 * n, (-0.5, 0.0, 0.0))
        deadline = time.monotonic() + 5.0
        while est.counters().get("imu_gyro_samples", 0) < 21 and time.monotonic() < deadline:
            est.at(math.inf)
            time.sleep(0.01)
        assert est.at(math.inf) == pytest.approx((0.0, math.cos(0.05), math.sin(0.05)), abs=1e-6)
    finally:
        sensor.stop()
        sensor.close()
    no_gyro = rs.software_device()
    only = no_gyro.add_sensor("Motion Module")
    m = rs.motion_stream()
    m.type, m.index, m.uid, m.fps, m.fmt = rs.stream.accel, 0, 5, 63, rs.format.motion_xyz32f
    m.intrinsics = rs.motion_device_intrinsic()
    only.add_motion_stream(m)
    sensor, _ = find_accel(rs, no_gyro)
    assert find_gyro(rs, sensor) is None
