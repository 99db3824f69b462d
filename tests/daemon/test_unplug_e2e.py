"""A source unplugged mid-run, through the real daemon: capture keeps reading the source, which reconnects by
itself (hal/errors.py), instead of closing and opening it again (a recording then started over from its first
frame, met the same unplug, and never ended)."""

from __future__ import annotations

import json

from tests.daemon.replay_util import replay_to_end

SQUAT = "reference/tfjs_pose_squats/pose_squats.mp4"


def _log_events(path) -> list[str]:
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line).get("event", ""))
        except ValueError:
            continue
    return out


def test_a_replay_unplugged_for_a_moment_goes_on_where_it_was(tmp_path, shared_data):
    source = f"{shared_data / SQUAT}?disconnect_at=10&disconnect_s=0.5"
    got = replay_to_end(tmp_path, source, "unplugbot", ("pose",), "pipeline.target_fps=30", timeout_s=90.0)
    seqs = [p["seq"] for p in got["pose"]]
    assert seqs, "no pose published"
    assert len(seqs) == len(set(seqs)), f"frames published twice (the recording started over): {seqs}"
    assert 10 not in seqs, "the frame lost to the unplug was published"
    assert max(seqs) >= 60 and min(seqs) <= 9, seqs       # before and after the unplug, to the end
    events = _log_events(tmp_path / "err.log") + _log_events(tmp_path / "out.log")
    assert events.count("camera_lost") == 1, events
    assert events.count("camera_back") == 1, events
    assert events.count("recording_ended") == 1, events
