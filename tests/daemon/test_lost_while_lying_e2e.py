"""A slow fall whose person the extractor loses while they lie on the floor, replayed through the real daemon
with the default config, as issue 33's private recordings are: the landmarks as MediaPipe Holistic gives them
(bench.falls_extractor: no elbows or wrists here), the person lost 0.3 s after lying began. The daemon
publishes ``on_floor`` with ``lost_while_lying`` on the fall topic, as ``posed falls`` finds offline; lost
after one lying frame only, nothing (docs/falls.md, "Falls that end out of sight")."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from posed.bench.falls_extractor import HOLISTIC_KEPT
from posed.bench.falls_scenarios import catalogue, frames
from posed.landmarks.recording import LandmarkFrame, RecordingHeader, write_recording
from tests.daemon.frame_sizes_util import ROOT, run_to_end

SLOW_FALL = "tune/fall/collapse/slow-v30"   # knees give way, sink, tip over: no fast descent


def _recording(path: Path, lose_at: float) -> Path:
    sc = next(s for s in catalogue("tune") if s.name == SLOW_FALL)
    cam = sc.camera
    out = []
    for fr in frames(sc):
        lm = None
        if fr.landmarks is not None and fr.t < lose_at:
            lm = np.full_like(fr.landmarks, np.nan)
            lm[list(HOLISTIC_KEPT)] = fr.landmarks[list(HOLISTIC_KEPT)]
        out.append(LandmarkFrame(fr.seq, fr.t, lm))
    write_recording(path, RecordingHeader((cam.width, cam.height), sc.fps, "synthetic slow fall", cam.intrinsics),
                    out)
    return path


def _offline(rec: Path) -> list[dict]:
    out = subprocess.run([sys.executable, "-m", "posed.cli", "falls", str(rec)], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def test_a_slow_fall_lost_while_lying_is_published_by_the_daemon(tmp_path):
    seen = _offline(_recording(tmp_path / "seen.landmarks.jsonl", 99.0))
    assert [e["state"] for e in seen] == ["on_floor"] and "lost_while_lying" not in seen[0]["features"]
    lying_start = seen[0]["t_impact"]

    rec = _recording(tmp_path / "lost.landmarks.jsonl", lying_start + 0.3)
    offline = _offline(rec)
    assert [e["state"] for e in offline] == ["on_floor"]
    assert "lost_while_lying" in offline[0]["features"]
    assert abs(offline[0]["t_detect"] - seen[0]["t_detect"]) < 1e-6

    run = run_to_end(tmp_path, f"file:{rec}", "source.realtime=false", timeout_s=90.0)
    assert run.code == 0, run.stderr[-2000:]
    events = list({(e["id"], e["state"]): e for e in run.got["events/fall"]}.values())
    assert [e["state"] for e in events] == ["on_floor"], [(e["state"], e["features"]) for e in events]
    ev = events[0]
    assert "lost_while_lying" in ev["features"] and ev["confidence"] <= 0.65
    # the daemon's times are on its own clock (the recording's shifted): from lying to the message, as offline
    # (within a frame: an unpaced replay may drop one)
    want = offline[0]["t_detect"] - offline[0]["t_impact"]
    assert abs((ev["t_detect"] - ev["t_impact"]) - want) <= 0.1 + 1e-6, (ev["t_detect"] - ev["t_impact"], want)


def test_lost_after_one_lying_frame_the_daemon_publishes_nothing(tmp_path):
    lying_start = _offline(_recording(tmp_path / "seen.landmarks.jsonl", 99.0))[0]["t_impact"]
    rec = _recording(tmp_path / "lost.landmarks.jsonl", lying_start + 0.05)
    assert _offline(rec) == []
    run = run_to_end(tmp_path, f"file:{rec}", "source.realtime=false", timeout_s=90.0)
    assert run.code == 0, run.stderr[-2000:]
    assert run.got["events/fall"] == []
    assert len(run.got["pose"]) >= 50
