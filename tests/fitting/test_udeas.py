"""uDEAS (paper section 2.4): the numba kernel against a plain-Python reference of the same steps, known
minima of standard test functions, determinism."""

import math

import numpy as np
import pytest

from posed.fitting import udeas

MASK = (1 << 64) - 1


def _splitmix(state):
    state[0] = (state[0] + 0x9E3779B97F4A7C15) & MASK
    z = state[0]
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def reference_udeas(f, lo, hi, restarts, m0, mf, seed):
    """Steps 1-7 of section 2.4 written out plainly (same random bits as the kernel)."""
    n = len(lo)
    state = [(seed * 0x2545F4914F6CDD1D + 0x632BE59BD9B4E019) & MASK]

    def d(code, bits, j):
        return lo[j] + (hi[j] - lo[j]) * code / ((1 << bits) - 1)

    best, best_x, evals = np.inf, None, 0
    for _ in range(restarts):
        m = m0
        rows = [_splitmix(state) >> (64 - m) for _ in range(n)]           # Step 1: random binary matrix
        v = [d(rows[j], m, j) for j in range(n)]
        cur = f(np.array(v))
        evals += 1
        while m < mf:
            bits = m + 1
            for j in range(n):                                              # Steps 2-5: one session per row
                k_minus, k_plus = 2 * rows[j], 2 * rows[j] + 1              # BSS: new LSB 0 / 1
                v[j] = d(k_minus, bits, j)
                c_minus = f(np.array(v))
                v[j] = d(k_plus, bits, j)
                c_plus = f(np.array(v))
                evals += 2
                u, k_best, c_best = (-1, k_minus, c_minus) if c_minus < c_plus else (1, k_plus, c_plus)
                while 0 <= k_best + u <= (1 << bits) - 1:                   # UDS while the cost falls
                    v[j] = d(k_best + u, bits, j)
                    c = f(np.array(v))
                    evals += 1
                    if c < c_best:
                        k_best, c_best = k_best + u, c
                    else:
                        break
                rows[j] = k_best
                v[j] = d(k_best, bits, j)
                cur = c_best
            m = bits                                                        # Step 6: longer rows
        if cur < best:                                                      # Step 7: keep the global best
            best, best_x = cur, list(v)
    return np.array(best_x), best, evals


# The reference's costs use the kernel's operations in the kernel's order (math.cos, which is the C library's
# cos as in numba, not numpy's vectorised one; left-to-right sums): both then see bit-identical costs, and a
# near-tie between two candidates cannot be decided one way here and the other way in the kernel (a 1e-16
# difference in a comparison would send the search down another path).
def rastrigin(v):
    acc = 10.0 * v.size
    for x in v:
        acc += x * x - 10.0 * math.cos(2.0 * math.pi * x)
    return acc


def rosenbrock(v):
    acc = 0.0
    for i in range(v.size - 1):
        a = v[i + 1] - v[i] * v[i]
        b = 1.0 - v[i]
        acc += 100.0 * a * a + b * b
    return acc


@pytest.mark.parametrize(("problem", "f", "bound"), [(udeas.PROBLEM_RASTRIGIN, rastrigin, 5.12),
                                                     (udeas.PROBLEM_ROSENBROCK, rosenbrock, 2.0)])
def test_kernel_matches_reference(problem, f, bound):
    lo, hi = np.full(3, -bound), np.full(3, bound)
    x, c, evals, _, _ = udeas.minimize(problem, lo, hi, restarts=4, m0=3, mf=9, seed=11)
    rx, rc, revals = reference_udeas(f, lo, hi, 4, 3, 9, 11)
    np.testing.assert_allclose(x, rx, rtol=0, atol=1e-12)
    assert c == pytest.approx(rc, rel=1e-12, abs=1e-12)
    assert evals == revals


def test_decode_rules():
    # appending 0 lowers, appending 1 raises the decoded value (paper section 2.4)
    for code in range(1, 7):
        parent = udeas.decode(code, 3, -1.0, 1.0)
        assert udeas.decode(2 * code, 4, -1.0, 1.0) < parent < udeas.decode(2 * code + 1, 4, -1.0, 1.0)
    assert udeas.decode(0, 5, -2.0, 3.0) == -2.0 and udeas.decode(31, 5, -2.0, 3.0) == 3.0
    assert udeas.encode(0.5, 8, 0.0, 1.0) in (127, 128)


@pytest.mark.parametrize("seed", range(4))
def test_rastrigin_2d_global_minimum(seed):
    x, c, _, _, _ = udeas.minimize(udeas.PROBLEM_RASTRIGIN, np.full(2, -5.12), np.full(2, 5.12), restarts=200, m0=5,
                                   mf=16, seed=seed)
    assert c < 1e-4 and np.abs(x).max() < 1e-3  # the global basin, to the 16-bit resolution


@pytest.mark.parametrize("n", [2, 5, 10])
def test_rosenbrock_global_minimum(n):
    x, c, _, _, _ = udeas.minimize(udeas.PROBLEM_ROSENBROCK, np.full(n, -2.0), np.full(n, 2.0), restarts=30, m0=1,
                                   mf=24, seed=0)
    assert c < 1e-4 and np.abs(x - 1).max() < 0.02


def test_sphere_10d_and_fixed_variables():
    lo, hi = np.full(10, -5.0), np.full(10, 5.0)
    lo[3] = hi[3] = 1.5  # held fixed
    x, c, _, _, _ = udeas.minimize(udeas.PROBLEM_SPHERE, lo, hi, restarts=3, m0=3, mf=20, seed=2)
    assert x[3] == 1.5
    assert c == pytest.approx(2.25, abs=1e-6)


def test_same_seed_same_result_and_initial_rows():
    lo, hi = np.full(4, -3.0), np.full(4, 3.0)
    a = udeas.minimize(udeas.PROBLEM_RASTRIGIN, lo, hi, restarts=5, m0=3, mf=10, seed=9)
    b = udeas.minimize(udeas.PROBLEM_RASTRIGIN, lo, hi, restarts=5, m0=3, mf=10, seed=9)
    other = udeas.minimize(udeas.PROBLEM_RASTRIGIN, lo, hi, restarts=5, m0=3, mf=10, seed=10)
    assert np.array_equal(a[3], b[3]) and a[2] == b[2]
    assert not np.array_equal(a[3], other[3])
    # a seeded restart starts from the given vector: with m0 == mf nothing moves
    x, _, evals, _, _ = udeas.minimize(udeas.PROBLEM_SPHERE, lo, hi, restarts=1, m0=12, mf=12, x_init=[0.5, -1, 2, 0])
    assert evals == 1
    np.testing.assert_allclose(x, [0.5, -1, 2, 0], atol=3e-3)


def test_a_held_variable_changes_nothing_else():
    """A variable with lo == hi draws no random bits and costs no evaluations: the others come out exactly as
    without it (the fit holds the upper arms' rotations so, and then searches exactly the paper's 19)."""
    lo, hi = np.full(3, -5.12), np.full(3, 5.12)
    x, c, evals, rx, rc = udeas.minimize(udeas.PROBLEM_RASTRIGIN, lo, hi, restarts=5, m0=3, mf=10, seed=4)
    lo4, hi4 = np.insert(lo, 1, 0.0), np.insert(hi, 1, 0.0)   # rastrigin(0) adds nothing to the cost
    x4, c4, evals4, rx4, rc4 = udeas.minimize(udeas.PROBLEM_RASTRIGIN, lo4, hi4, restarts=5, m0=3, mf=10, seed=4)
    assert np.array_equal(np.delete(x4, 1), x) and x4[1] == 0.0
    assert c4 == c and evals4 == evals
    assert np.array_equal(np.delete(rx4, 1, axis=1), rx) and np.array_equal(rc4, rc)
