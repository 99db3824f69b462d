"""Shared test fixtures. The real data must sit at ../shared/data: without it the run fails, never skips."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = Path(os.environ.get("POSED_SHARED_DATA", ROOT.parent / "shared" / "data"))


def pytest_sessionstart(session: pytest.Session) -> None:
    if not (SHARED_DATA / "README.md").is_file():
        raise pytest.UsageError(
            f"the real test data is missing: {SHARED_DATA} (CI puts ../shared beside the clone; "
            "set POSED_SHARED_DATA to point elsewhere)"
        )


@pytest.fixture(scope="session")
def shared_data() -> Path:
    return SHARED_DATA


@pytest.fixture(autouse=True)
def _logs_to_stdout():
    """structlog's configuration is process-wide: a command run in an earlier test (e.g. `posed record`, which
    logs to stderr) must not decide where a later test's log lines go."""
    from posed.daemon import logs

    logs.configure("info", "json")
