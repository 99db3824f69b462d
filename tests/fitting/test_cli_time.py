"""``posed fit`` of a recording whose clock goes backwards: every frame is fitted, and the user is told where
(the frame is fitted on its own, not from the one before)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_a_clock_going_backwards_is_said_and_nothing_lost(tmp_path, shared_data):
    lines = (shared_data / "falls/urfd_dev/urfd_00_fall.landmarks.jsonl").read_text().splitlines()[:41]
    out = [lines[0]]
    for i, line in enumerate(lines[1:]):
        obj = json.loads(line)
        if i == 30:
            obj["t"] -= 0.5
        out.append(json.dumps(obj))
    rec = tmp_path / "back.landmarks.jsonl"
    rec.write_text("\n".join(out) + "\n")
    r = subprocess.run([sys.executable, "-m", "posed.cli", "fit", str(rec), "-o", str(tmp_path / "f.jsonl")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "1 frame(s) with a time `t` earlier than the frame before (first: seq 30)" in r.stderr, r.stderr
    fits = [json.loads(x) for x in (tmp_path / "f.jsonl").read_text().splitlines()]
    assert [f["seq"] for f in fits] == list(range(40))
    assert next(f for f in fits if f["seq"] == 30)["mode"] == "image"
