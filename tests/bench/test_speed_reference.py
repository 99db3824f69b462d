"""The speed reference (bench.speed_reference): a fixed workload whose result never changes and whose time
grows with the work asked."""

import math

import numpy as np
import pytest

from posed.bench.speed_reference import SIZE, reference_ms, workload


def reference_workload(rounds: int) -> float:
    """The same power iteration in plain NumPy."""
    i, j = np.indices((SIZE, SIZE))
    a = 1.0 / (1.0 + i + j) + np.eye(SIZE)
    v = np.ones(SIZE)
    acc = 0.0
    for _ in range(rounds):
        w = a @ v
        norm = math.sqrt(float(w @ w))
        v = w / norm
        acc += norm
    return acc / rounds


@pytest.mark.parametrize("rounds", [1, 7, 500])
def test_the_workload_matches_a_numpy_reference(rounds):
    assert workload(rounds) == pytest.approx(reference_workload(rounds), rel=1e-12)


def test_the_workload_converges_to_the_largest_eigenvalue():
    i, j = np.indices((SIZE, SIZE))
    top = np.linalg.eigvalsh(1.0 / (1.0 + i + j) + np.eye(SIZE)).max()
    # the running mean of the norms tends to the dominant eigenvalue: the loop does the work it says
    assert workload(200_000) == pytest.approx(top, rel=1e-4)


def test_reference_ms_is_a_positive_time_and_checks_its_arguments():
    assert reference_ms(repeats=3, rounds=2000) > 0
    with pytest.raises(ValueError, match="at least 1"):
        reference_ms(repeats=0)
