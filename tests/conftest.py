"""Shared test fixtures. The real data must sit at ../shared/data: without it the run fails, never skips."""

from __future__ import annotations

import os
import subprocess
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


@pytest.fixture
def tmpfs(tmp_path):
    """``tmpfs(size)``: a fresh tmpfs of that size (``1m``, ``300k``) under tmp_path, unmounted afterwards: a real
    tiny disk to fill up (as root; skipped with the reason where mounting is not permitted)."""
    mounted: list[Path] = []

    def mount(size: str) -> Path:
        if os.geteuid() != 0:
            pytest.skip("mounting a tmpfs needs root; this test fills a real tiny disk")
        mnt = tmp_path / f"tmpfs{len(mounted)}"
        mnt.mkdir()
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)],
                           capture_output=True, text=True)
        if r.returncode:
            pytest.skip(f"this machine does not let the test mount a tmpfs: {r.stderr.strip()}")
        mounted.append(mnt)
        return mnt

    try:
        yield mount
    finally:
        for mnt in mounted:
            if subprocess.run(["umount", str(mnt)], capture_output=True).returncode:
                subprocess.run(["umount", "-l", str(mnt)], capture_output=True)
