"""Fixtures of the bad-input tests of the command line: a five-frame landmark recording cut from a real one, its
fit results, a joint-angle history, a crafted PNG whose header claims 60000 x 60000 pixels, and a real, full
tmpfs (mounted as root; the tests that need it skip, saying why, where mounting is not permitted)."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from posed.cli import main

URFD = Path("falls") / "urfd_dev" / "urfd_00_fall.landmarks.jsonl"


def posed(*args: str, stdout=subprocess.PIPE, timeout: float = 120) -> subprocess.CompletedProcess:
    """The real command in its own process (stdout may be a file such as /dev/full)."""
    return subprocess.run([sys.executable, "-m", "posed", *args], stdout=stdout, stderr=subprocess.PIPE,
                          text=True, timeout=timeout)


@pytest.fixture(scope="session")
def tiny(shared_data, tmp_path_factory) -> Path:
    """The header and the first five frames of a real recording."""
    lines = (shared_data / URFD).read_text(encoding="utf-8").splitlines(keepends=True)[:6]
    path = tmp_path_factory.mktemp("rec") / "tiny.landmarks.jsonl"
    path.write_text("".join(lines), encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def fit_file(tiny, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("fit") / "tiny.fit.jsonl"
    assert main(["fit", str(tiny), "-o", str(path)]) == 0
    assert len(path.read_text().splitlines()) == 5
    return path


@pytest.fixture
def history_db(tmp_path) -> Path:
    from posed.daemon.history.store import AngleHistory
    from posed.falls.config import FallsConfig
    from posed.fitting import JOINT_ANGLE_NAMES, FitResult

    path = tmp_path / "h.sqlite3"
    with AngleHistory(path, FallsConfig(history_rate_hz=10.0)) as hist:
        for i in range(20):
            angles = {name: 10.0 + i + k for k, name in enumerate(JOINT_ANGLE_NAMES)}
            hist.add(FitResult(seq=i, t=i / 10.0, ok=True, joint_angles_deg=angles), wall=1_700_000_000 + i / 10.0)
    return path


def huge_png(path: Path, width: int = 60000, height: int = 60000) -> Path:
    """A valid 8x8 PNG whose IHDR (with a correct CRC) claims ``width`` x ``height``."""
    ok, buf = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    assert ok
    data = bytearray(buf.tobytes())
    assert data[12:16] == b"IHDR"
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    path.write_bytes(bytes(data))
    return path


@pytest.fixture
def full_dir(tmp_path) -> Path:
    """A real 64 kB tmpfs, filled up: every write into it fails with ENOSPC. Unmounted afterwards."""
    mnt = tmp_path / "full"
    mnt.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tiny tmpfs to fill up needs root (mount -t tmpfs)")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"mount -t tmpfs is not permitted here: {r.stderr.strip()}")
    try:
        with open(mnt / "filler", "wb", buffering=0) as fh:
            try:
                while True:
                    fh.write(b"\0" * 4096)
            except OSError:
                pass
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=False)
