"""uDEAS, the univariate Dynamic Encoding Algorithm for Searches (paper section 2.4), in numba.

Each of the n variables is a binary row of the matrix M; a row of m bits ``r`` decodes to
``lo + (hi - lo) * int(r) / (2**m - 1)``, so appending 0 (1) as a new least significant bit lowers (raises)
the decoded value (the paper's rule). One restart:

1. M gets random bits, m = m0 (Step 1).
2. For each row j in turn (Steps 2-5): BSS tries both new LSBs and keeps the better one (its direction u_j);
   UDS then adds u_j to the row while the cost keeps falling, and the best row goes back into M.
3. When every row had its session, m grows by one, until the rows are m_f bits long (Step 6).
4. Restarts repeat from 1; the smallest cost over all restarts is the result (Step 7).

The cost is chosen by an integer ``problem`` (numba cannot cache a kernel that takes a function argument):
0 = the pose loss of :mod:`fitting.loss`, 1 = sphere, 2 = Rastrigin, 3 = Rosenbrock (test functions
to validate the optimizer, as the uDEAS papers do). Random bits come from a SplitMix64 generator seeded by
``seed``: the same seed gives the same result.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from posed.fitting import loss as LOSS

PROBLEM_POSE, PROBLEM_SPHERE, PROBLEM_RASTRIGIN, PROBLEM_ROSENBROCK = 0, 1, 2, 3


@njit(cache=True)
def splitmix64(state):
    """Next 64-bit random number; ``state`` is a 1-element uint64 array updated in place."""
    state[0] = state[0] + np.uint64(0x9E3779B97F4A7C15)
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def sphere(v):
    acc = 0.0
    for x in v:
        acc += x * x
    return acc


@njit(cache=True)
def rastrigin(v):
    acc = 10.0 * v.size
    for x in v:
        acc += x * x - 10.0 * math.cos(2.0 * math.pi * x)
    return acc


@njit(cache=True)
def rosenbrock(v):
    acc = 0.0
    for i in range(v.size - 1):
        a = v[i + 1] - v[i] * v[i]
        b = 1.0 - v[i]
        acc += 100.0 * a * a + b * b
    return acc


@njit(cache=True)
def cost(problem, v, data, work):
    if problem == PROBLEM_POSE:
        return LOSS.pose_loss(v, data, work)
    if problem == PROBLEM_SPHERE:
        return sphere(v)
    if problem == PROBLEM_RASTRIGIN:
        return rastrigin(v)
    return rosenbrock(v)


@njit(cache=True)
def decode(code, bits, lo, hi):
    """d(r): a row of ``bits`` bits with integer value ``code`` -> a real in [lo, hi]."""
    top = (1 << bits) - 1
    return lo + (hi - lo) * code / top


@njit(cache=True)
def encode(value, bits, lo, hi):
    """The row of ``bits`` bits that decodes nearest to ``value``."""
    top = (1 << bits) - 1
    if hi <= lo:
        return 0
    k = int(round((value - lo) / (hi - lo) * top))
    return min(max(k, 0), top)


@njit(cache=True)
def udeas(problem, lo, hi, restarts, m0, mf, seed, data, work, x_init, n_init, out_x, out_restart_x,
          out_restart_cost):
    """Minimize ``cost(problem, .)``; restart r searches the box [lo[r], hi[r]] (2-D arrays, one row per
    restart: several hypotheses can share one run).

    The first ``n_init`` restarts start from the rows nearest to ``x_init[r]`` instead of random bits
    (video mode: the previous frame's solution). Returns (best cost, number of cost evaluations); the
    best vector goes to ``out_x`` and each restart's result to ``out_restart_x[r]`` / ``out_restart_cost[r]``.
    A variable with lo == hi is held fixed and draws no random bits: a held variable changes nothing else.
    """
    n = lo.shape[1]
    state = np.empty(1, dtype=np.uint64)
    state[0] = np.uint64(seed) * np.uint64(0x2545F4914F6CDD1D) + np.uint64(0x632BE59BD9B4E019)
    rows = np.zeros(n, dtype=np.int64)
    v = np.empty(n)
    best = np.inf
    evals = 0
    if mf < m0:
        mf = m0
    for r in range(restarts):
        m = m0
        lo_r = lo[r]
        hi_r = hi[r]
        for j in range(n):
            if r < n_init:
                rows[j] = encode(x_init[r, j], m, lo_r[j], hi_r[j])
            elif hi_r[j] <= lo_r[j]:
                rows[j] = 0   # held: no random bits drawn for it (the others' draws as without it)
            else:
                rows[j] = np.int64(splitmix64(state) >> np.uint64(64 - m))
            v[j] = decode(rows[j], m, lo_r[j], hi_r[j])
        cur = cost(problem, v, data, work)
        evals += 1
        while m < mf:
            bits = m + 1
            top = (1 << bits) - 1
            for j in range(n):
                lj = lo_r[j]
                hj = hi_r[j]
                if hj <= lj:
                    rows[j] = rows[j] * 2
                    continue
                # BSS: a new least significant bit, 0 (down) or 1 (up)
                k_minus = rows[j] * 2
                k_plus = k_minus + 1
                v[j] = decode(k_minus, bits, lj, hj)
                c_minus = cost(problem, v, data, work)
                v[j] = decode(k_plus, bits, lj, hj)
                c_plus = cost(problem, v, data, work)
                evals += 2
                if c_minus < c_plus:
                    u = -1
                    k_best = k_minus
                    c_best = c_minus
                else:
                    u = 1
                    k_best = k_plus
                    c_best = c_plus
                # UDS: keep stepping in the better direction while the cost falls
                while True:
                    k_new = k_best + u
                    if k_new < 0 or k_new > top:
                        break
                    v[j] = decode(k_new, bits, lj, hj)
                    c_new = cost(problem, v, data, work)
                    evals += 1
                    if c_new < c_best:
                        k_best = k_new
                        c_best = c_new
                    else:
                        break
                rows[j] = k_best
                v[j] = decode(k_best, bits, lj, hj)
                cur = c_best
            m = bits
        for j in range(n):
            out_restart_x[r, j] = v[j]
        out_restart_cost[r] = cur
        if cur < best:
            best = cur
            for j in range(n):
                out_x[j] = v[j]
    return best, evals


def minimize(problem: int, lo, hi, *, restarts: int = 6, m0: int = 3, mf: int = 6, seed: int = 0,
             data=None, work=None, x_init=None):
    """Python front end: returns (best x, best cost, evals, restart xs, restart costs).

    ``lo``, ``hi``: one box (1-D) for every restart, or one row per restart (2-D).
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    if lo.shape != hi.shape or lo.ndim not in (1, 2):
        raise ValueError("lo and hi must be arrays of the same shape, 1-D or (restarts, n)")
    lo = np.ascontiguousarray(np.broadcast_to(lo, (restarts, lo.shape[-1])))
    hi = np.ascontiguousarray(np.broadcast_to(hi, (restarts, hi.shape[-1])))
    if not 1 <= m0 <= 40 or not 1 <= mf <= 40:
        raise ValueError(f"row lengths m0={m0}, mf={mf} must be in 1..40")
    n = lo.shape[1]
    data = np.zeros(1) if data is None else data
    work = np.zeros((1, 3)) if work is None else work
    inits = np.zeros((0, n)) if x_init is None else np.atleast_2d(np.asarray(x_init, dtype=np.float64))
    out_x = np.empty(n)
    rx = np.empty((restarts, n))
    rc = np.empty(restarts)
    best, evals = udeas(problem, lo, hi, restarts, m0, mf, seed, data, work,
                        np.ascontiguousarray(inits) if inits.size else np.zeros((1, n)), len(inits), out_x, rx, rc)
    return out_x, best, evals, rx, rc
