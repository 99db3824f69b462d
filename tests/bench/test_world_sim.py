"""The simulated world-landmark stream of the out-of-domain protocol (bench.world_sim): it reproduces the two
statistics it was set from (BlazePose's world landmarks on real video, issue 38: 21 % wrong limb depth signs,
median PA-MPJPE 77 mm), hip-centred like BlazePose's, with gross failures on about 4.5 % of frames."""

from __future__ import annotations

import numpy as np

from posed.bench import mocap_landmarks as M
from posed.bench import ood as O
from posed.bench import world_sim as W


def _truth(shared_data, az: float, fps: int = 10) -> np.ndarray:
    clip = M.load_clip(shared_data / "mocap" / "cmu" / "131_01.bvh")
    return O.build_sequence(clip, az, fps, (0.0,), seed=1).truth


def test_the_stream_has_the_statistics_it_was_set_from(shared_data):
    checks = [W.calibration_check(_truth(shared_data, az), 10.0, seed=int(az)) for az in (0.0, 90.0, 180.0, 270.0)]
    sign = np.mean([c["depth_sign_wrong"] for c in checks])
    median = np.mean([c["pa_mpjpe_median_mm"] for c in checks])
    # the targets are 21 % and 77 mm; four views of one clip leave a few points of sampling spread
    assert 0.16 <= sign <= 0.26, checks
    assert 67.0 <= median <= 87.0, checks


def test_hip_centred_body_joints_only_and_gross_failures(shared_data):
    truth = _truth(shared_data, 45.0, fps=30)
    world = W.simulate_world(truth, 30.0, np.random.default_rng(3))
    assert world.shape == (len(truth), 33, 5)
    body = world[:, M.BODY12_IDX]
    assert np.isfinite(body).all() and np.isnan(np.delete(world, M.BODY12_IDX, axis=1)).all()
    mid = 0.5 * (body[:, 6, :3] + body[:, 7, :3])
    assert np.abs(mid).max() < 1e-12
    # gross failures: a wrong body is more than 20 cm off even after the similarity (the drifting noise alone
    # stays below); 4.5 % of frames on average, in episodes of 0.3 s, so counted over ten seeds' streams
    gross = []
    for seed in range(10):
        w = W.simulate_world(truth, 30.0, np.random.default_rng(seed))[:, M.BODY12_IDX, :3]
        gross += [O.pa_mpjpe(a, t) > 0.2 for a, t in zip(w, truth, strict=True)]
    assert 0.02 < np.mean(gross) < 0.08, np.mean(gross)
    again = W.simulate_world(truth, 30.0, np.random.default_rng(3))
    assert np.array_equal(again, world, equal_nan=True)   # explicit seed: reproducible
