"""``posed config check --source URI`` probes the source: size, orientation and rate of real clips and what the
daemon will do with them (the same scale factor and thinning the capture stage uses); a source that cannot
give a frame is a problem (exit 78), never an OK."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _check(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", "config", "check", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_a_landscape_clip_above_the_working_size(shared_data):
    r = _check("--source", f"file:{shared_data / 'reference/multi_person/s2d_enter.mp4'}")
    assert r.returncode == 0, r.stderr
    assert "a recording, 1768x994, 30 fps" in r.stdout and "230 frames (7.7 s)" in r.stdout, r.stdout
    assert "scales each frame down by 2 to 884x497" in r.stdout, r.stdout
    assert "takes 10 of the 30 frames per second" in r.stdout, r.stdout
    assert r.stdout.rstrip().endswith(": OK")


def test_a_portrait_5_fps_clip_within_the_working_size(shared_data, tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("pipeline:\n  stop_at_end: true\n")
    r = _check(str(cfg), "--source", f"file:{shared_data / 'reference/tfjs_pose_squats/pose_squats.mp4'}")
    assert r.returncode == 0, r.stderr
    assert "720x1280 portrait, 5 fps" in r.stdout and "at their own size" in r.stdout, r.stdout
    assert "takes every frame" in r.stdout and "stops at its end" in r.stdout, r.stdout
    assert f"{cfg}: OK" in r.stdout


def test_a_file_that_gives_no_frame_is_a_problem(tmp_path):
    bad = tmp_path / "cut.mp4"
    bad.write_bytes(b"\x00\x00\x00\x18ftypmp42" + b"\x00" * 64)      # an MP4 cut short after its type box
    r = _check("--source", f"file:{bad}")
    assert r.returncode == 78, (r.returncode, r.stdout, r.stderr)
    assert "source:" in r.stderr and str(bad) in r.stderr and "OK" not in r.stdout, r.stderr


def test_a_landmark_recording(shared_data):
    r = _check("--source", f"file:{shared_data / 'falls/urfd_dev/urfd_04_fall.landmarks.jsonl'}")
    assert r.returncode == 0, r.stderr
    assert "a landmark recording, 640x480, 30 fps, 135 frames" in r.stdout, r.stdout
