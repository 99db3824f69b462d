"""The capture clock of every replay (hal.ReplayClock, docs/hal.md "Clock jumps"): recorded steps are kept, a
repeated, backward or leaping timestamp is one frame period after the frame before, and the time line goes on
from there; through a real video replay with a timestamps sidecar, paced and unpaced alike."""

from __future__ import annotations

import json
import math

import cv2
import pytest

from posed import hal
from posed.hal import ReplayClock


def test_recorded_steps_are_kept():
    c = ReplayClock()
    assert [c.map(t, 0.1) for t in (5.0, 5.1, 5.35, 65.35)] == pytest.approx([5.0, 5.1, 5.35, 65.35])
    assert c.jumps == 0


@pytest.mark.parametrize(("stamps", "expected"), [
    ((0.0, 0.1, 0.1, 0.2), (0.0, 0.1, 0.2, 0.3)),                    # a repeated stamp
    ((0.0, 0.1, -999.9, -999.8), (0.0, 0.1, 0.2, 0.3)),              # the clock went back 1000 s
    ((0.0, 0.1, 1e9, 1e9 + 0.1), (0.0, 0.1, 0.2, 0.3)),              # a leap of 1e9 s forward
    ((0.0, 0.1, math.nan, 0.3), (0.0, 0.1, 0.2, 0.3)),               # not a number: one period
])
def test_a_clock_jump_is_one_period_and_the_line_goes_on(stamps, expected):
    c = ReplayClock()
    assert [c.map(t, 0.1) for t in stamps] == pytest.approx(expected)
    assert c.jumps == 1


def test_a_gap_up_to_a_minute_is_a_gap():
    c = ReplayClock()
    assert [c.map(t, 0.1) for t in (0.0, 59.0, 120.5)] == pytest.approx([0.0, 59.0, 59.1])
    assert c.jumps == 1


def _clip_with_sidecar(tmp_path, squat_frames, rels):
    path = tmp_path / "jump.avi"
    h, w = squat_frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w // 4, h // 4))
    for i in range(len(rels)):
        vw.write(cv2.resize(squat_frames[i % len(squat_frames)], (w // 4, h // 4)))
    vw.release()
    lines = [{"format": "posed.timestamps", "version": 1, "source": "test", "fps": 10.0,
              "image_size": [w // 4, h // 4]}]
    lines += [{"frame": i, "seq": i, "t": t} for i, t in enumerate(rels)]
    (tmp_path / "jump.timestamps.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    return path


@pytest.mark.parametrize("realtime", [False, True])
def test_a_replay_with_jumping_timestamps_is_the_same_paced_or_not(tmp_path, squat_frames, realtime):
    """Stamps leap 1e9 s forward, repeat, then go back 1000 s: a paced replay neither waits nor bursts, and
    hands out the same time line as an unpaced one."""
    rels = [0.0, 0.1, 0.2, 1e9, 1e9 + 0.1, 1e9 + 0.1, 1e9 - 1000.0, 1e9 - 999.9]
    path = _clip_with_sidecar(tmp_path, squat_frames, rels)
    ts = []
    with hal.open_source(f"file:{path}?realtime={str(realtime).lower()}") as src:
        for _ in rels:
            ts.append(src.read(timeout_s=1.0).t)
        jumps = src.info["clock_jumps"]
    steps = [round(b - a, 3) for a, b in zip(ts, ts[1:], strict=False)]
    assert steps == [0.1] * 7, steps       # one period (the sidecar's 10 fps) at each of the 3 jumps
    assert jumps == 3
