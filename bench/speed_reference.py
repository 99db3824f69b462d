"""How fast this machine runs right now: a fixed CPU workload timed next to a benchmark.

The shared VM's speed drifts by up to 1.5x between hours (docs/bench/fit.md, runs I-K): a per-frame time from
one run cannot be compared with another run's unless both say how fast the machine was. :func:`reference_ms`
times a workload that never changes with the fitter's code: a numba loop of the same kind of work as the
refinement (small dense matrix-vector products, a square root per product and a division per element, no memory traffic
beyond a few kilobytes), on one core, CPU time of the calling thread, the median of several repeats. Divide
a benchmark's ``ms_per_frame`` by ``speed_ref_ms`` (``posed bench fit --json``, ``machine``) to compare runs
made at different speeds.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

SIZE = 19          # the refinement's number of variables
ROUNDS = 100_000   # about 12 ms on the 2-core AMD EPYC VM at its faster hours (2026-12-02)


@njit(cache=True)
def workload(rounds: int) -> float:
    """``rounds`` products of a fixed 19 x 19 matrix with a vector, each normalized: a deterministic number
    (the same on every machine up to rounding), so that the work cannot be optimized away."""
    a = np.empty((SIZE, SIZE))
    for i in range(SIZE):
        for j in range(SIZE):
            a[i, j] = 1.0 / (1.0 + i + j) + (1.0 if i == j else 0.0)
    v = np.ones(SIZE)
    w = np.empty(SIZE)
    acc = 0.0
    for _ in range(rounds):
        norm = 0.0
        for i in range(SIZE):
            s = 0.0
            for j in range(SIZE):
                s += a[i, j] * v[j]
            w[i] = s
            norm += s * s
        norm = math.sqrt(norm)
        for i in range(SIZE):
            v[i] = w[i] / norm
        acc += norm
    return acc / rounds


def reference_ms(repeats: int = 7, rounds: int = ROUNDS) -> float:
    """The median CPU time (ms, this thread) of :func:`workload` over ``repeats`` runs, after one run that
    compiles or loads it."""
    if repeats < 1 or rounds < 1:
        raise ValueError(f"repeats ({repeats}) and rounds ({rounds}) must be at least 1")
    workload(1)
    times = []
    for _ in range(repeats):
        c0 = time.thread_time()
        workload(rounds)
        times.append(time.thread_time() - c0)
    return round(float(np.median(times)) * 1000.0, 3)
