"""The capture clock of a replay through the real daemon (issue 34 item 6, issue 35): a real fall recording
whose timestamps leap 1e9 s forward, or repeat and then go back 1000 s, replays paced in its own length and
publishes the fall events `posed falls` finds in the original, as unpaced; a looping landmark recording's seq keeps increasing (docs/hal.md)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.daemon.frame_sizes_util import ROOT, run_to_end
from tests.daemon.zenoh_util import client, free_port

FALL = Path("falls") / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"     # 4.5 s, a fall at ~3.2 s


def _with_times(src: Path, dst: Path, change) -> Path:
    lines = src.read_text().splitlines()
    out = [lines[0]]
    for i, line in enumerate(lines[1:]):
        frame = json.loads(line)
        frame["t"] = change(i, frame["t"])
        out.append(json.dumps(frame))
    dst.write_text("\n".join(out) + "\n")
    return dst


def _offline_states(rec: Path) -> list[str]:
    out = subprocess.run([sys.executable, "-m", "posed.cli", "falls", str(rec)], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return [json.loads(line)["state"] for line in out.stdout.splitlines() if line.startswith("{")]


def _repeat_then_back(i: int, t: float) -> float:
    if 30 <= i < 34:
        return 29 / 30            # four frames repeat the time of frame 29
    return t - 1000.0 if i >= 34 else t


@pytest.mark.parametrize(("name", "change"), [
    ("leap", lambda i, t: t + 1e9 if i >= 30 else t),
    ("repeat_then_back", _repeat_then_back),
])
@pytest.mark.parametrize("realtime", [True, False])
def test_a_recording_whose_clock_jumps_replays_in_its_length_and_the_fall_is_found(tmp_path, shared_data, name,
                                                                                   change, realtime):
    rec = _with_times(shared_data / FALL, tmp_path / f"{name}.landmarks.jsonl", change)
    t0 = time.monotonic()
    run = run_to_end(tmp_path, f"file:{rec}", f"source.realtime={str(realtime).lower()}", timeout_s=60.0)
    took = time.monotonic() - t0
    assert run.code == 0, run.stderr[-2000:]
    assert took < 40.0, took              # 4.5 s of recording (+ start-up), never the 1e9 s leap
    # each jump is one frame period, as the recorded steps were: the time line is the original recording's, so
    # the fall detector says what `posed falls` says on the original (a paced replay used to burst through
    # the 1000 frames' worth of the step back, dropping them, and miss the fall)
    # one entry per message (event id and state): the daemon republishes unacknowledged messages when it sees a
    # subscriber appear (which under load it may notice after the first publication), and every 30 s
    states = [state for _id, state in dict.fromkeys((e["id"], e["state"]) for e in run.got["events/fall"])]
    assert states == _offline_states(shared_data / FALL), (
        [(e["id"][:8], e["state"]) for e in run.got["events/fall"]], [p["t"] for p in run.got["pose"]][25:40])
    assert len(run.got["pose"]) >= 0.9 * 45, len(run.got["pose"])
    ts = [p["t"] for p in run.got["pose"]]
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False)), ts
    jumps = run.events("clock_jump")
    assert jumps, "a clock jump was not logged"


def test_a_looping_landmark_recording_continues_seq(tmp_path, shared_data):
    """Two passes of a real recording, unpaced: the poses' seq keeps increasing over the loop (it used to start
    at 0 again), and t keeps increasing too."""
    rec = shared_data / FALL
    frames_per_pass = 45                   # 135 frames at 30 fps taken at 10 fps
    ep = f"tcp/127.0.0.1:{free_port()}"
    poses: list[dict] = []
    lock = threading.Lock()

    def on(sample) -> None:
        with lock:
            poses.append(json.loads(sample.payload.to_string()))

    with open(tmp_path / "out.log", "w") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "run", "--source",
                                 f"file:{rec}?loop=true&realtime=false", "--set", f"zenoh.listen=[{ep}]",
                                 "--set", f"pipeline.state_dir={tmp_path / 'state'}", "--set", "robot_id=loop",
                                 "--set", "logging.format=json"], cwd=ROOT, stdout=fh, stderr=subprocess.STDOUT)
    try:
        with client(ep) as s:
            _sub = s.declare_subscriber("posed/loop/pose", on)
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline and len(poses) < frames_per_pass * 2 + 10:
                assert proc.poll() is None, (tmp_path / "out.log").read_text()[-2000:]
                time.sleep(0.1)
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(30)
    with lock:
        seqs = [p["seq"] for p in poses]
        ts = [p["t"] for p in poses]
    assert len(seqs) >= frames_per_pass * 2, len(seqs)
    assert all(b > a for a, b in zip(seqs, seqs[1:], strict=False)), seqs
    assert all(b > a for a, b in zip(ts, ts[1:], strict=False))
    assert max(seqs) > 135, max(seqs)     # past the recording's last seq: the second pass goes on from it


@pytest.mark.parametrize(("name", "change"), [
    ("leap", lambda i, t: t + 1e9 if i >= 30 else t),
    ("repeat_then_back", _repeat_then_back),
])
def test_posed_falls_uses_the_same_capture_clock(tmp_path, shared_data, name, change):
    """Offline, the same rule: `posed falls` on the recording whose clock jumps says what it says on the
    original, at the same times (it used to restart the detector at the step back)."""
    rec = _with_times(shared_data / FALL, tmp_path / f"{name}.landmarks.jsonl", change)

    def events(path: Path) -> list[tuple[str, float]]:
        out = subprocess.run([sys.executable, "-m", "posed.cli", "falls", str(path)], cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        return [(e["state"], round(e["t_detect"], 3)) for e in
                (json.loads(x) for x in out.stdout.splitlines() if x.startswith("{"))]

    got, want = events(rec), events(shared_data / FALL)
    assert [e[0] for e in got] == [e[0] for e in want], (got, want)
    # at most one frame (0.1 s) apart: timestamps near 1e9 s carry only 1e-7 s of precision, which can move a
    # detector's threshold across one frame
    assert all(abs(a[1] - b[1]) <= 0.1 + 1e-6 for a, b in zip(got, want, strict=True)), (got, want)
    if name == "repeat_then_back":
        assert got == want
