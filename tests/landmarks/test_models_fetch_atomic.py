"""`posed models fetch` on a robot whose models work, when the new files cannot all be written: a real tiny
disk that fills up half way, a file system remounted read-only. The fetch says what is wrong and the fix, and
the models that worked before still pass the daemon's start-up check, byte for byte as they were."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from posed.daemon.config import load_config
from posed.daemon.preflight import check
from posed.landmarks.models import MANIFEST, MODEL_FILES, find_models, verify_models

ROOT = Path(__file__).resolve().parents[2]
# the folder holds about 34 MB: 40 MB leaves room for the first new file but not for the whole new set
DISK = "40m"


def fetch(models: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", "models", "fetch", "--models-dir", str(models),
                           *extra], capture_output=True, text=True, cwd=ROOT, timeout=300)


def contents(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def daemon_would_start(models: Path, tmp_path: Path) -> list[str]:
    """The problems `posed run` stops on (daemon.preflight.check) with this models folder."""
    cfg = load_config(None, [f"landmarks.models_dir={models}", f"pipeline.state_dir={tmp_path / 'state'}"])
    return check(cfg)


@pytest.fixture
def on_tiny_disk(models_dir, tmpfs) -> Path:
    folder = tmpfs(DISK) / "models"
    folder.mkdir()
    for name in (*MODEL_FILES, MANIFEST):
        shutil.copy(models_dir / name, folder / name)
    verify_models(find_models(folder), include_tflite=True)
    return folder


def test_a_disk_full_half_way_leaves_the_working_models_as_they_were(on_tiny_disk, tmp_path):
    before = contents(on_tiny_disk)
    proc = fetch(on_tiny_disk, "--force")
    assert proc.returncode == 73, proc.stdout + proc.stderr
    assert "no space left" in proc.stderr and "--models-dir" in proc.stderr
    assert contents(on_tiny_disk) == before          # no temporary left, nothing replaced, the manifest kept
    assert daemon_would_start(on_tiny_disk, tmp_path) == []


def test_a_read_only_file_system_is_named_read_only(on_tiny_disk, tmp_path):
    before = contents(on_tiny_disk)
    mount_point = on_tiny_disk.parent
    r = subprocess.run(["mount", "-o", "remount,ro", str(mount_point)], capture_output=True, text=True)
    if r.returncode:
        pytest.skip(f"cannot remount the tmpfs read-only: {r.stderr.strip()}")
    try:
        proc = fetch(on_tiny_disk, "--force")
    finally:
        subprocess.run(["mount", "-o", "remount,rw", str(mount_point)], capture_output=True)
    assert proc.returncode == 73, proc.stdout + proc.stderr
    assert "read-only" in proc.stderr and "permission denied" not in proc.stderr
    assert str(on_tiny_disk) in proc.stderr and "--models-dir" in proc.stderr
    assert contents(on_tiny_disk) == before
    assert daemon_would_start(on_tiny_disk, tmp_path) == []


def test_a_fetch_with_room_replaces_every_file(models_dir, tmp_path):
    """Guard: the same --force with room converts again and leaves only the five files."""
    folder = tmp_path / "models"
    shutil.copytree(models_dir, folder)
    before = contents(folder)
    os.utime(folder / MANIFEST, (0, 0))
    proc = fetch(folder, "--force")
    assert proc.returncode == 0, proc.stderr
    after = contents(folder)
    assert sorted(after) == sorted(before)
    assert {k: v for k, v in after.items() if k != MANIFEST} == {k: v for k, v in before.items() if k != MANIFEST}
    assert (folder / MANIFEST).stat().st_mtime > 0
    verify_models(find_models(folder), include_tflite=True)
