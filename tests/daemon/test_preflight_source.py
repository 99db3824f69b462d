"""A source file posed cannot read is found before anything starts (issue 34 item 8): a landmark recording
without its ``.landmarks.jsonl`` suffix passed the start-up checks, then stopped the daemon with 78 after the
stages had spawned; now ``posed run`` and ``posed config check`` refuse it at once and say to rename it."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from posed.hal.registry import file_problem

ROOT = Path(__file__).resolve().parents[2]
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"


def test_a_landmark_recording_without_its_suffix_is_refused_before_any_stage(tmp_path):
    rec = tmp_path / "fall.jsonl"
    shutil.copy(REAL, rec)
    r = subprocess.run([sys.executable, "-m", "posed.cli", "run", "--source", f"file:{rec}", "--set",
                        "pipeline.stop_at_end=true", "--set", f"pipeline.state_dir={tmp_path / 'state'}"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 78, r.stderr[-2000:]
    assert "fall.landmarks.jsonl" in r.stderr and "rename" in r.stderr
    assert "stage_start" not in r.stdout + r.stderr           # nothing was spawned


def test_file_problem_knows_what_hal_opens(tmp_path):
    junk = tmp_path / "x.xyz"
    junk.write_bytes(b"junk")
    assert "not a video" in file_problem(junk)
    assert file_problem(REAL) is None
    assert file_problem(tmp_path / "clip.mp4") is None            # a missing file is another check's problem
    video = ROOT.parent / "shared" / "data" / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    odd = tmp_path / "squats.video"
    shutil.copy(video, odd)
    assert file_problem(odd) is None                               # any name, if it opens as a video
