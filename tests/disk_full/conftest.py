"""The short real recordings the disk-full tests run the commands on (the tiny tmpfs to fill up is the shared
``tmpfs`` fixture of tests/conftest.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT, SHARED_DATA

FALL = SHARED_DATA / "falls" / "urfd_dev" / "urfd_00_fall.landmarks.jsonl"
SQUAT_VIDEO = SHARED_DATA / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"


def posed(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """The real command line, from the checkout."""
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def short_recording(path: Path, frames: int) -> Path:
    """The header and the first ``frames`` frame lines of a real landmark recording (the URFD fall)."""
    with FALL.open(encoding="utf-8") as fh:
        lines = [next(fh) for _ in range(frames + 1)]
    path.write_text("".join(lines), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def short_fit(tmp_path_factory):
    """(a 12-frame landmark recording, its fit by ``posed fit``)."""
    folder = tmp_path_factory.mktemp("short")
    rec = short_recording(folder / "fall.landmarks.jsonl", 12)
    fit = folder / "fit.jsonl"
    r = posed("fit", str(rec), "-o", str(fit))
    assert r.returncode == 0, r.stderr
    return rec, fit
