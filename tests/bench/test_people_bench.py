"""``posed bench people`` on one composited scenario (the woman of the squat video and the man of pose2sim's
balancing video side by side): the report has its documented shape, nobody's identity switches, the man is
found, and the woman's landmarks with him in view are within 1.2x her error alone (issue 36's target)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_people_bench_apart():
    r = subprocess.run([sys.executable, "-m", "posed.cli", "bench", "people", "--json", "--scenario", "apart"],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads(r.stdout)
    (row,) = report["scenarios"]
    assert report["benchmark"] == "people" and row["scenario"] == "apart" and row["frames"] == 65
    assert row["identity_switches"] == {"a": 0, "b": 0}
    assert row["found"]["a_both"] > 0.95 and row["found"]["b_both"] > 0.8, row["found"]
    assert row["a_error_px"]["ratio"] <= report["targets"]["a_error_ratio_max"], row["a_error_px"]
    assert row["landmark_passes_per_frame"] > 1.5 and row["ms_per_frame"]["two_people"] > 0
