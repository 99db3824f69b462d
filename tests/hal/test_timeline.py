"""The replay time line shared by the file sources and RealSense playback, with a scripted clock; and the
choice of recording sink by output name."""

from __future__ import annotations

import numpy as np
import pytest

from posed import hal
from posed.hal.frame import Frame
from posed.hal.recorder import _Db3Sink, _ImageSink, _VideoSink, check_output
from posed.hal.replay import Timeline


class FakeClock:
    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def _frame(line: Timeline, rel: float, seq_in_pass: int) -> Frame:
    t, seq = line.time_at(rel), line.add_frame(seq_in_pass)
    return Frame(image=np.zeros((2, 2, 3), np.uint8), depth=None, depth_scale=0.0, t=t, seq=seq, intrinsics=None)


def test_loop_continues_time_one_period_after_the_last_frame_and_seq_after_the_last_seq():
    clock = FakeClock()
    line = Timeline("test", clock, clock.sleep)
    first = line.read(1.0, lambda deadline: _frame(line, line.since_first(50.0), 0), realtime=False)
    second = line.read(1.0, lambda deadline: _frame(line, line.since_first(50.2), 1), realtime=False)
    assert (first.t, first.seq, second.t, second.seq) == (100.0, 0, pytest.approx(100.2), 1)
    assert line.end_of_pass(loop=True, frame_period=lambda: 0.2)
    third = line.read(1.0, lambda deadline: _frame(line, line.since_first(50.0), 0), realtime=False)
    assert (third.t, third.seq) == (pytest.approx(100.4), 2)
    assert line.pass_frames == 1 and not line.ended


def test_an_empty_pass_or_no_loop_ends_without_asking_the_period():
    def no_period() -> float:
        raise AssertionError("the period is needed only for another pass")

    clock = FakeClock()
    line = Timeline("test", clock, clock.sleep)
    assert not line.end_of_pass(loop=True, frame_period=no_period) and line.ended
    line = Timeline("test", clock, clock.sleep)
    line.read(1.0, lambda deadline: _frame(line, 0.0, 0), realtime=False)
    assert not line.end_of_pass(loop=False, frame_period=no_period) and line.ended


def test_realtime_frame_due_after_the_timeout_stays_pending():
    clock = FakeClock()
    line = Timeline("test", clock, clock.sleep)
    produced = []

    def produce(deadline: float) -> Frame:
        produced.append(deadline)
        return _frame(line, 0.5 * len(produced) - 0.5, len(produced) - 1)

    assert line.read(0.3, produce, realtime=True).seq == 0
    with pytest.raises(hal.SourceTimeout, match="due in 0.20 s"):
        line.read(0.3, produce, realtime=True)  # frame 1 is due at 100.5; the read gives up at 100.3
    assert line.pending is not None and line.pending.seq == 1
    again = line.read(0.3, produce, realtime=True)
    assert (again.seq, again.t, clock.now, len(produced)) == (1, 100.5, pytest.approx(100.5), 2)


def test_a_stamp_before_the_first_is_a_clock_jump_not_a_step_back():
    clock = FakeClock()
    line = Timeline("test", clock, clock.sleep)
    line.t_start = 100.0
    ts = [line.time_at(line.since_first(s), 0.1) for s in (10.0, 10.25, 9.0, 9.05)]
    assert ts == pytest.approx([100.0, 100.25, 100.35, 100.40])     # one period after, then the recorded step
    assert line.clock.jumps == 1


@pytest.mark.parametrize(("name", "sink"), [("a.db3", _Db3Sink), ("a.MKV", _VideoSink), ("dir/a.avi", _VideoSink),
                                            ("a.mp4", _VideoSink), ("frames", _ImageSink)])
def test_check_output_names_the_sink(name, sink):
    assert check_output(name) is sink


def test_check_output_refuses_other_suffixes():
    with pytest.raises(hal.SourceUnsupported, match=r"x\.gif: cannot record to '\.gif'; use \.mkv"):
        check_output("x.gif")
