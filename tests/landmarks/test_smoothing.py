import math

import numpy as np
import pytest

from posed.landmarks.smoothing import (
    AUX_PARAMS,
    LANDMARK_PARAMS,
    VISIBILITY_ALPHA,
    WORLD_PARAMS,
    LowPass,
    OneEuro,
    OneEuroParams,
    PoseSmoother,
)


class _ScalarOneEuro:
    """MediaPipe's OneEuroFilter for one value, written out plainly (seconds instead of nanoseconds)."""

    def __init__(self, min_cutoff, beta, dcutoff):
        self.freq, self.min_cutoff, self.beta, self.dcutoff = 30.0, min_cutoff, beta, dcutoff
        self.last_t = None
        self.x_raw = self.x_val = self.dx_val = None

    def alpha(self, cutoff):
        te = 1.0 / self.freq
        tau = 1.0 / (2 * math.pi * cutoff)
        return 1.0 / (1.0 + tau / te)

    def apply(self, t, value_scale, x):
        if self.last_t is not None:
            if self.last_t >= t:
                return x
            self.freq = 1.0 / (t - self.last_t)
        self.last_t = t
        dx = 0.0 if self.x_raw is None else (x - self.x_raw) * value_scale * self.freq
        a = self.alpha(self.dcutoff)
        self.dx_val = dx if self.dx_val is None else a * dx + (1 - a) * self.dx_val
        cutoff = self.min_cutoff + self.beta * abs(self.dx_val)
        a = self.alpha(cutoff)
        self.x_val = x if self.x_val is None else a * x + (1 - a) * self.x_val
        self.x_raw = x
        return self.x_val


def test_parameters_are_mediapipes_current_ones():
    assert (LANDMARK_PARAMS.min_cutoff, LANDMARK_PARAMS.beta, LANDMARK_PARAMS.derivate_cutoff) == (0.05, 80.0, 1.0)
    assert (WORLD_PARAMS.min_cutoff, WORLD_PARAMS.beta, WORLD_PARAMS.value_scaling) == (0.1, 40.0, False)
    assert (AUX_PARAMS.min_cutoff, AUX_PARAMS.beta) == (0.01, 10.0)
    assert VISIBILITY_ALPHA == 0.1


def test_low_pass_first_sample_passes_then_blends():
    f = LowPass(0.1)
    assert f.apply(np.array([10.0])) == pytest.approx([10.0])
    assert f.apply(np.array([20.0])) == pytest.approx([11.0])
    f.reset()
    assert f.apply(np.array([5.0])) == pytest.approx([5.0])
    with pytest.raises(ValueError):
        LowPass(1.5)


def test_one_euro_matches_the_scalar_reference():
    rng = np.random.default_rng(11)
    params = OneEuroParams(0.05, 80.0)
    f = OneEuro(params)
    refs = [_ScalarOneEuro(0.05, 80.0, 1.0) for _ in range(6)]
    t = 0.0
    for k in range(40):
        t = t + rng.uniform(0.01, 0.2) if k != 20 else t  # one repeated timestamp
        x = rng.normal(100, 20, 6) + 5 * k
        scale = 1 / rng.uniform(100, 400)
        got = f.apply(t, x, scale)
        want = [r.apply(t, scale, float(xi)) for r, xi in zip(refs, x, strict=True)]
        assert np.allclose(got, want)


def test_one_euro_keeps_a_still_value_and_follows_a_jump():
    f = OneEuro(LANDMARK_PARAMS)
    for k in range(10):
        assert f.apply(k / 30, np.array([50.0]), 1 / 300)[0] == pytest.approx(50.0)
    moved = f.apply(10 / 30, np.array([150.0]), 1 / 300)[0]
    assert 50.0 < moved < 150.0


def _frame(offset=0.0, aux_gap=100.0):
    lms = np.zeros((33, 5))
    lms[:, 0] = np.arange(33) * 10 + offset
    lms[:, 1] = 200 + offset
    lms[:, 3] = 0.9
    lms[:, 4] = 0.95
    aux = np.array([[300 + offset, 400, 0, 0.9, 0.9], [300 + offset, 400 - aux_gap, 0, 0.9, 0.9]])
    return lms, aux, np.ones((33, 3)) * 0.1


def test_pose_smoother_first_frame_passes_through_and_reset_forgets():
    s = PoseSmoother()
    lms, aux, world = _frame()
    out, aux_out, world_out, vis_out = s.apply(0.0, lms, aux, world)
    assert np.allclose(out, lms) and np.allclose(aux_out, aux) and np.allclose(world_out, world)
    lms2, aux2, world2 = _frame(offset=40.0)
    lms2[:, 3] = 0.1
    out2, aux2_out, _, vis2_out = s.apply(1 / 30, lms2, aux2, world2)
    assert (out2[:, 0] < lms2[:, 0]).all() and (out2[:, 0] > lms[:, 0]).all()
    assert np.allclose(out2[:, 3], 0.1 * 0.1 + 0.9 * 0.9)            # visibility low-pass
    assert np.array_equal(vis2_out, out2[:, 3])                      # the world landmarks' visibility
    assert (np.abs(aux2_out[:, 0] - aux[:, 0]) < np.abs(out2[:, 0] - lms[:, 0]).min()).all()  # aux heavier
    s.reset()
    out3, _, _, _ = s.apply(2 / 30, lms2, aux2, world2)
    assert np.allclose(out3, lms2)


def test_pose_smoother_bypasses_a_degenerate_object_scale():
    s = PoseSmoother()
    s.apply(0.0, *_frame(aux_gap=0.0))
    lms2, aux2, world2 = _frame(offset=40.0, aux_gap=0.0)
    out, aux_out, _, _ = s.apply(1 / 30, lms2, aux2, world2)
    assert np.allclose(out[:, :3], lms2[:, :3]) and np.allclose(aux_out[:, :3], aux2[:, :3])


def test_pose_smoother_off_still_filters_the_aux_landmarks():
    s = PoseSmoother(smooth_landmarks=False)
    s.apply(0.0, *_frame())
    lms2, aux2, world2 = _frame(offset=40.0)
    out, aux_out, world_out, _ = s.apply(1 / 30, lms2, aux2, world2)
    assert np.array_equal(out, lms2) and np.array_equal(world_out, world2)
    assert (aux_out[:, 0] < aux2[:, 0]).all()
