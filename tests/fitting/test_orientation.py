"""The orientation seeds kernel (fitting.orientation) against the plain-Python function it replaced (with the
NumPy body-angle inverse), to the last bit, and what the seeds are for: the body's facing from the hips and
shoulders, both depth mirrors."""

import math

import numpy as np
import pytest

from posed.fitting import layout as L
from posed.fitting import orientation as O
from posed.fitting import problem as P
from posed.fitting.body import BodyDimensions
from posed.fitting.config import FitConfig
from posed.fitting.kinematics import R0, body_angles_from_rotation, body_rotation
from posed.fitting.warmup import POSE, warmup_landmarks

DIMS = BodyDimensions.from_height(1.7)
DEG = math.pi / 180.0
LEVEL = np.zeros(10)   # the camera is level (fitting.layout.D_LEVEL)


def reference_seeds(obs: list[float], w: list[float], dims: BodyDimensions, lo: np.ndarray,
                    hi: np.ndarray) -> np.ndarray:
    """The seeds in plain Python floats (the function the kernel replaced)."""
    if not (w[0] > 0 and w[1] > 0 and w[6] > 0 and w[7] > 0):
        return np.zeros((0, L.N_VAR))
    o, h = obs, dims.body_height_m
    a = [0.5 * ((o[12 + i] - o[14 + i]) * h / (2 * dims.hip_half_m) + (o[i] - o[2 + i]) * h / (2 * dims.shoulder_half_m))
         for i in (0, 1)]
    b = [(0.5 * (o[i] + o[2 + i]) - 0.5 * (o[12 + i] + o[14 + i])) * h / dims.trunk_m for i in (0, 1)]
    na, nb = np.hypot((a[0], b[0]), (a[1], b[1])).tolist()
    ab = a[0] * b[0] + a[1] * b[1]
    ya_mag = math.sqrt(max(0.0, 1.0 - min(na, 1.0) * min(na, 1.0)))
    zb_mag = math.sqrt(max(0.0, 1.0 - min(nb, 1.0) * min(nb, 1.0)))
    candidates = []
    for ya in (ya_mag, -ya_mag):
        if ya_mag > 0.2:
            candidates.append((ya, math.copysign(zb_mag, -ab / ya)))
        else:
            candidates.extend([(ya, zb_mag), (ya, -zb_mag)])
    seeds = []
    for ya, zb in candidates:
        ny = math.sqrt(a[0] * a[0] + a[1] * a[1] + ya * ya)
        if ny < 1e-6:
            continue
        ey = (a[0] / ny, a[1] / ny, ya / ny)
        dot = b[0] * ey[0] + b[1] * ey[1] + zb * ey[2]
        ez = (b[0] - dot * ey[0], b[1] - dot * ey[1], zb - dot * ey[2])
        nz = math.sqrt(ez[0] * ez[0] + ez[1] * ez[1] + ez[2] * ez[2])
        if nz < 1e-6:
            continue
        ez = (ez[0] / nz, ez[1] / nz, ez[2] / nz)
        ex = (ey[1] * ez[2] - ey[2] * ez[1], ey[2] * ez[0] - ey[0] * ez[2], ey[0] * ez[1] - ey[1] * ez[0])
        t, p, s = body_angles_from_rotation(np.array([ex, ey, ez]).T)
        x = np.zeros(L.N_VAR)
        x[0] = 1.0
        x[L.X_TBD], x[L.X_PBD], x[L.X_SBD] = t * DEG, p * DEG, s * DEG
        seeds.append(np.minimum(np.maximum(x, lo), hi))
    return np.array(seeds) if seeds else np.zeros((0, L.N_VAR))


def _frame(noise_px: float, seed: int) -> P.Frame:
    cfg = FitConfig()
    xy, w, _ = P.landmark_weights(warmup_landmarks(DIMS, noise_px, seed), cfg)
    return P.pack(xy, w, DIMS, cfg, P.reference_scale(xy, w, DIMS))


def test_signed_rows_are_those_of_r0():
    """Row i of R0^T is s times the unit row k, (k, s) = R0T_ROWS[i]."""
    for i, (k, s) in enumerate(O.R0T_ROWS):
        want = np.zeros(3)
        want[k] = s
        np.testing.assert_array_equal(R0.T[i], want)


def test_seed_angles_are_the_numpy_inverse_to_the_last_bit():
    """The kernel's body angles of the pelvis axes against fitting.kinematics.body_angles_from_rotation:
    rotations and arbitrary matrices, zeros of both signs and the gimbal case included."""
    rng = np.random.default_rng(6)
    lo, hi = np.full(L.N_VAR, -np.inf), np.full(L.N_VAR, np.inf)
    out = np.empty(L.N_VAR)
    for i in range(3000):
        r = body_rotation(*rng.uniform(-180, 180, 3)) if i % 2 else rng.normal(size=(3, 3))
        r[rng.random((3, 3)) < 0.2] = 0.0
        r[rng.random((3, 3)) < 0.2] *= -1.0
        if i % 7 == 0:
            r[1, 1] = rng.choice([1.0, -1.0, 0.0, -0.0])
        O._seed(tuple(r[:, 0].tolist()), tuple(r[:, 1].tolist()), tuple(r[:, 2].tolist()), lo, hi, out)
        want = np.array(body_angles_from_rotation(r)) * DEG
        assert out[[L.X_TBD, L.X_PBD, L.X_SBD]].tobytes() == want.tobytes()


@pytest.mark.parametrize("bounds", ["paper", "wide"])
def test_kernel_matches_the_python_function_to_the_last_bit(bounds):
    """Random torsos (every facing, lying, edge-on: the 4-seed branch) and both search boxes."""
    lo, hi = P.image_box(FitConfig(bounds=bounds))
    rng = np.random.default_rng(7)
    frame = _frame(0.0, 1)
    w = frame.weights.copy()
    edge_on = 0
    for trial in range(3000):
        obs = frame.data[L.D_OBS:L.D_OBS + 24].copy()
        obs[[0, 1, 2, 3, 12, 13, 14, 15]] = rng.normal(0.0, 0.15, 8)
        if trial % 5 == 0:   # the shoulders and the hips on one vertical line: edge-on
            obs[[0, 2, 12, 14]] = obs[0]
            edge_on += 1
        if trial % 97 == 0:
            obs[[2, 3]] = obs[[0, 1]]   # both shoulders on one point
        got = np.empty((O.MAX_SEEDS, L.N_VAR))
        n = O.orientation_seeds_into(obs, w, DIMS.body_height_m, DIMS.hip_half_m, DIMS.shoulder_half_m,
                                     DIMS.trunk_m, lo, hi, LEVEL, got)
        want = reference_seeds(obs.tolist(), w.tolist(), DIMS, lo, hi)
        assert n == len(want)
        np.testing.assert_array_equal(got[:n], want)
    assert edge_on > 0


def test_no_seeds_without_both_hips_and_shoulders():
    frame = _frame(0.0, 1)
    lo, hi = P.image_box(FitConfig())
    for i in (0, 1, 6, 7):
        w = frame.weights.copy()
        w[i] = 0.0
        out = np.empty((O.MAX_SEEDS, L.N_VAR))
        assert O.orientation_seeds_into(frame.data[L.D_OBS:L.D_OBS + 24], w, DIMS.body_height_m, DIMS.hip_half_m,
                                        DIMS.shoulder_half_m, DIMS.trunk_m, lo, hi, LEVEL, out) == 0


def test_a_turned_person_gets_the_true_facing_and_its_depth_mirror():
    """The warm-up person stands turned 30 degrees about the vertical (fitting.warmup.POSE): one seed has that
    yaw, the other its depth mirror (-30: the same hip and shoulder lines in the image); limbs straight,
    gamma 1."""
    frame = _frame(0.0, 1)
    lo, hi = P.image_box(FitConfig())
    seeds = P.orientation_seeds(frame, DIMS, lo, hi)
    assert len(seeds) == 2
    assert np.all(seeds[:, 0] == 1.0)
    others = np.delete(seeds, [0, L.X_TBD, L.X_PBD, L.X_SBD], axis=1)
    assert np.all(others == 0.0)
    yaw = sorted(math.degrees(v) for v in seeds[:, L.X_SBD])
    assert POSE.psi_bd == 30.0
    np.testing.assert_allclose(yaw, [-30.0, 30.0], atol=1.0)
