"""`posed models fetch` after a fetch that was killed (kill -9, a power cut) while writing: the hidden
temporaries it left (``.<model file>.tmp<pid>``, up to 12 MB each, never taken for a model) are removed by
the next fetch, which says so; nothing else in the folder is touched, nor a temporary of a fetch still
running."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.landmarks.convert.fetch import fetch_models
from posed.landmarks.models import find_models, verify_models

ROOT = Path(__file__).resolve().parents[2]


def dead_pid() -> int:
    """The pid of a process that has exited (and was reaped)."""
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          check=True)
    pid = int(proc.stdout)
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return pid
    pytest.skip(f"pid {pid} was reused at once")


@pytest.fixture
def folder(models_dir, tmp_path) -> Path:
    """A copy of the real, complete models folder."""
    target = tmp_path / "models"
    shutil.copytree(models_dir, target)
    return target


def leave_temporaries(folder: Path) -> tuple[list[Path], list[Path]]:
    """(what an interrupted fetch leaves: the start of a real model file under its temporary name, written
    by a fetch that is gone; files that must stay)."""
    pid = dead_pid()
    stale = folder / f".pose_detection.onnx.tmp{pid}"
    stale.write_bytes((folder / "pose_detection.onnx").read_bytes()[:65536])   # cut off mid-write
    old = folder / f".manifest.json.tmp{os.getppid()}"          # a live pid, but written an hour ago: reused
    old.write_text("{")
    hour_ago = time.time() - 3600
    os.utime(old, (hour_ago, hour_ago))
    running = folder / f".pose_landmark_full.onnx.tmp{os.getpid()}x"   # not the pattern (trailing x)
    running.write_bytes(b"1")
    keep = [folder / ".notes.tmp1", folder / f"pose_detection.onnx.tmp{pid}", folder / ".pose_detection.onnx.tmp",
            folder / f".other.onnx.tmp{pid}", running]
    for p in keep:
        p.write_bytes(b"not the fetch's")
    return [stale, old], keep


def test_the_next_fetch_removes_them_and_says_so(folder):
    stale, keep = leave_temporaries(folder)
    r = subprocess.run([sys.executable, "-m", "posed.cli", "models", "fetch", "--models-dir", str(folder)],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (f"posed models: removed 2 temporary file(s) left in {folder} by an interrupted fetch (0.1 MB): "
            in r.stdout), r.stdout
    for p in stale:
        assert p.name in r.stdout and not p.exists()
    assert all(p.exists() for p in keep)
    assert "up to date" in r.stdout                           # and the folder itself was complete
    verify_models(find_models(folder), include_tflite=True)


def test_a_fetch_that_converts_again_removes_them_too(folder):
    stale, keep = leave_temporaries(folder)
    (folder / "manifest.json").unlink()                       # as a fetch killed during its writes leaves it
    said: list[str] = []
    result = fetch_models(folder, say=said.append)
    assert result.changed
    assert sorted(result.removed_temporaries) == sorted(p.name for p in stale)
    assert any("interrupted fetch" in s for s in said), said
    assert not any(p.exists() for p in stale) and all(p.exists() for p in keep)
    verify_models(find_models(folder), include_tflite=True)


def test_a_running_fetchs_temporary_is_not_stale(folder):
    """A temporary whose writer is alive and that is fresh belongs to a fetch running now."""
    from posed.landmarks.convert.fetch import stale_temporaries

    mine = folder / f".pose_detection.tflite.tmp{os.getppid()}"
    mine.write_bytes(b"x")
    assert stale_temporaries(folder) == []
    gone = folder / f".pose_detection.tflite.tmp{dead_pid()}"
    gone.write_bytes(b"x")
    assert stale_temporaries(folder) == [gone]


def test_nothing_said_when_there_is_nothing_to_remove(folder):
    said: list[str] = []
    result = fetch_models(folder, say=said.append)
    assert not result.changed and result.removed_temporaries == () and said == []
