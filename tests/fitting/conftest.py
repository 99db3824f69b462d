"""Fixtures of the fitting tests."""

import pytest

from posed.fitting import jitcache


@pytest.fixture(scope="session", autouse=True)
def fresh_numba_cache() -> None:
    """Empty a stale numba cache of the kernels before any test runs one (many call kernels directly,
    without the ``Fitter`` that does this in the product)."""
    jitcache.ensure_fresh()
