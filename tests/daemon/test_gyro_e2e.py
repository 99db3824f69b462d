"""The RealSense gyro through ``posed run``, real processes end to end: a recording whose camera tilts down at
20 deg/s for its 2.2 s (the real squat video's colour; accelerometer samples at 63 Hz and gyro samples at 200 Hz
consistent with the turn, as tests/hal/test_imu_gyro.py writes them) -> capture (gravity on the FrameRef) ->
landmark stage -> the landmarks topic carries each frame's gravity, which follows the turn; the same
accelerometer samples through the accelerometer-only filter lag it by about rate * tau. The status' camera says
the gyro is streaming."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.hal.imu import G_M_S2, GravityEstimate
from tests.daemon.replay_util import replay_to_end
from tests.hal.test_imu_gyro import ACCEL_HZ, FRAMES, SQUAT_FPS, _down, angle_deg, write_turning_db3


def accel_only(times: list[float]) -> list[tuple[float, float, float] | None]:
    """Each frame's gravity from the recording's accelerometer samples alone (what the daemon gave before the
    gyro: hal.imu's filter without gyro samples, as tests/daemon/test_imu_e2e.py checks it end to end)."""
    est = GravityEstimate()
    out, n = [], 0
    for t in times:
        while n / ACCEL_HZ <= t + 1e-9:
            est.add(n / ACCEL_HZ, *(-G_M_S2 * _down(n / ACCEL_HZ)))
            n += 1
        out.append(est.at(t))
    return out


@pytest.mark.timeout(300)
def test_gyro_gravity_follows_a_turning_camera_through_the_daemon(tmp_path, squat_frames):
    recording = tmp_path / "turning.db3"
    times = write_turning_db3(recording, squat_frames)
    got = replay_to_end(tmp_path, recording, "gyro", ("landmarks", "status"), "pipeline.status_period_s=0.1",
                        "zenoh.publish_landmarks=true")
    msgs = sorted(got["landmarks"], key=lambda m: m["seq"])
    assert [m["seq"] for m in msgs] == list(range(FRAMES))
    cameras = [s["camera"] for s in got["status"] if s.get("camera", {}).get("gyro")]
    assert cameras and cameras[-1]["imu"] == "streaming" and cameras[-1]["gyro"] == "streaming"
    before = accel_only(times)
    lagging = 0
    for m, t, old in zip(msgs, times, before, strict=True):
        assert m["seq"] / SQUAT_FPS == pytest.approx(t)
        if m["seq"] == 0:
            continue                                   # one accelerometer sample before frame 0: no gravity yet
        err = angle_deg(m["gravity"], _down(t))
        # the gyro turns the average up to the frame: within one gyro period's turn (5 ms at 20 deg/s)
        assert err < 0.1, (m["seq"], err)
        if t >= 1.5:                                   # 3 time constants after the start: the steady lag
            lag = angle_deg(old, _down(t))
            assert lag > 6.0 and err < lag / 50.0, (m["seq"], lag, err)
            lagging += 1
    assert lagging >= 4
    tilts = [math.degrees(math.atan2(m["gravity"][2], m["gravity"][1])) for m in msgs[1:]]
    assert tilts[-1] - tilts[0] == pytest.approx(20.0 * (times[-1] - times[1]), abs=0.2)
    assert np.all(np.diff(tilts) > 0)
