"""Line readers facing a 2 GB line or /dev/zero: ``posed fit``, the landmark recording reader, the timestamps
sidecar, the config file and the calibration file each stop with a clear error naming the file and the
limit, in bounded memory (the CLI runs under a 3 GB address-space limit: reading such a line whole would
fail with a MemoryError traceback)."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RECORDING = "falls/urfd_dev/urfd_18_adl.landmarks.jsonl"


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


def posed(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, preexec_fn=_limited)


def _huge_line_after(tmp_path: Path, head: bytes, name: str) -> Path:
    """``head`` then a 2 GB line of NUL bytes without a newline (a sparse file: no disk used)."""
    path = tmp_path / name
    with open(path, "wb") as fh:
        fh.write(head)
        fh.truncate(len(head) + (2 << 30))
    return path


def test_posed_fit_on_dev_zero_is_a_clear_error():
    r = posed("fit", "/dev/zero")
    assert r.returncode == 2, r.stderr[-2000:]
    assert "Traceback" not in r.stderr and "MemoryError" not in r.stderr
    assert "/dev/zero:1:" in r.stderr and "longer than" in r.stderr


def test_posed_fit_on_a_2_gb_line_reports_it_and_stops(tmp_path, shared_data):
    lines = (shared_data / RECORDING).read_bytes().splitlines(keepends=True)
    path = _huge_line_after(tmp_path, b"".join(lines[:4]), "huge.landmarks.jsonl")
    r = posed("fit", str(path), "-o", str(tmp_path / "fits.jsonl"))
    assert r.returncode == 1, r.stderr[-2000:]
    assert "Traceback" not in r.stderr
    assert f"{path}:5:" in r.stderr and "longer than" in r.stderr
    assert len((tmp_path / "fits.jsonl").read_text().splitlines()) == 3          # the frames before it


def test_config_check_on_dev_zero_and_a_huge_calibration(tmp_path):
    r = posed("config", "check", "/dev/zero")
    assert r.returncode == 78 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "larger than" in r.stderr
    calib = _huge_line_after(tmp_path, b"format: posed.calibration\n", "user.yaml")
    r = posed("config", "check", str(ROOT / "config.yaml"), "--set", f"fitting.calibration={calib}")
    assert r.returncode == 78 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "fitting.calibration" in r.stderr and "larger than" in r.stderr


def test_posed_fit_with_dev_zero_as_calibration(shared_data):
    r = posed("fit", str(shared_data / RECORDING), "--set", "fitting.calibration=/dev/zero", "-o", "/dev/null")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "fitting.calibration: /dev/zero is larger than" in r.stderr


def test_recording_reader_stops_at_an_over_long_line(tmp_path, shared_data):
    from posed.landmarks import RecordingProblem, iter_recording

    lines = (shared_data / RECORDING).read_bytes().splitlines(keepends=True)
    path = tmp_path / "long.landmarks.jsonl"
    path.write_bytes(b"".join(lines[:3]) + b"x" * (4 << 20) + b"\n" + b"".join(lines[3:6]))
    _, stream = iter_recording(path)
    items = list(stream)
    assert [type(i).__name__ for i in items] == ["LandmarkFrame", "LandmarkFrame", "RecordingProblem"]
    assert isinstance(items[-1], RecordingProblem) and items[-1].line == 4 and "longer than" in items[-1].message


def test_sidecar_with_a_huge_line_is_a_clear_error(tmp_path):
    import cv2
    import numpy as np

    from posed import hal
    from posed.hal import SourceError

    cv2.imwrite(str(tmp_path / "img_0.png"), np.zeros((8, 8, 3), np.uint8))
    head = json.dumps({"format": "posed.timestamps", "version": 1}).encode() + b"\n"
    _huge_line_after(tmp_path, head, "timestamps.jsonl")
    src = hal.open_source(f"file:{tmp_path}")
    with pytest.raises(SourceError, match="longer than"):
        src.open()
        src.read(1.0)
    src.close()
