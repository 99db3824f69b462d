"""Device clock -> monotonic mapping, against a plain reference on simulated arrivals."""

from __future__ import annotations

import numpy as np

from posed.hal.clock import DeviceClock, wall_to_monotonic


def simulate(n: int, seed: int, offset: float, drift_ppm: float = 0.0):
    rng = np.random.default_rng(seed)
    capture = 100.0 + np.arange(n) / 30.0                      # true capture times, monotonic clock
    device = (capture - offset) * (1 + drift_ppm * 1e-6)        # the camera's own clock
    delay = 0.004 + rng.exponential(0.006, n)                   # USB + driver delay, always > 0
    return capture, device, capture + delay


def reference_min_filter(device, arrival, window):
    out = []
    for i in range(len(device)):
        lo = max(0, i - window + 1)
        out.append(device[i] + np.min(arrival[lo:i + 1] - device[lo:i + 1]))
    return np.minimum(np.array(out), arrival)


def test_matches_the_plain_reference_and_removes_jitter():
    capture, device, arrival = simulate(600, seed=1, offset=-5000.0)
    clock = DeviceClock(window=120)
    mapped = np.array([clock.map(d, a) for d, a in zip(device, arrival, strict=True)])
    assert np.allclose(mapped, reference_min_filter(device, arrival, 120), atol=1e-12)
    err_mapped = mapped[60:] - capture[60:]
    err_arrival = arrival[60:] - capture[60:]
    assert np.abs(err_mapped - np.median(err_mapped)).max() < 0.004  # jitter gone, only the ~4 ms floor left
    assert err_arrival.std() > 3 * err_mapped.std()
    assert np.all(mapped <= arrival)


def test_follows_drift_and_restarts_on_a_jump():
    capture, device, arrival = simulate(900, seed=2, offset=20.0, drift_ppm=200.0)
    clock = DeviceClock(window=60)
    mapped = np.array([clock.map(d, a) for d, a in zip(device, arrival, strict=True)])
    assert np.abs(mapped[100:] - capture[100:]).max() < 0.02
    before = clock.resets
    clock.map(0.5, arrival[-1] + 0.033)  # the camera restarted and counts from 0 again
    assert clock.resets == before + 1


def test_wall_to_monotonic():
    import time

    # the monotonic time at which the wall time was read, bracketed by two monotonic reads (no scheduling
    # allowance needed); 1e-6 s: four float64 steps of a Unix time near 1.7e9 s (2^-22 s each)
    before = time.monotonic()
    mapped = wall_to_monotonic(time.time())
    after = time.monotonic()
    assert before - 1e-6 <= mapped <= after + 1e-6
