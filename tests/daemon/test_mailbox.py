"""Latest-value mailboxes: the newest message wins, replaced messages count as drops, and a reader killed
with SIGKILL while waiting leaves nothing locked for the next one."""

import multiprocessing
import os
import signal
import time

from posed.daemon.proc.control import Control


def test_newest_wins_and_drops_are_counted():
    ctx = multiprocessing.get_context("spawn")
    control = Control.create(("a", "b"), {"frames": ctx.Semaphore(0)})
    try:
        box = control.mailbox("frames")
        assert box.take() is None
        assert box.put(("m", 1)) is False
        assert box.put(("m", 2)) is True          # 1 was never taken: a drop
        assert box.pending()
        assert box.take() == ("m", 2)
        assert box.take() is None and not box.pending()
        assert box.put(("m", 3)) is False
        assert box.wait(0.01) == ("m", 3)
        t0 = time.monotonic()
        assert box.wait(0.2) is None
        assert 0.15 < time.monotonic() - t0 < 2.0
    finally:
        control.close()


def _reader(spec, bells, out):
    control = Control.attach(spec, bells)
    box = control.mailbox("frames")
    out.put(os.getpid())
    while True:
        msg = box.wait(0.5)
        if msg is not None:
            out.put(msg)


def test_killed_reader_leaves_nothing_locked():
    ctx = multiprocessing.get_context("spawn")
    bells = {"frames": ctx.Semaphore(0)}
    control = Control.create(("a",), bells)
    out = ctx.Queue()
    try:
        box = control.mailbox("frames")
        first = ctx.Process(target=_reader, args=(control.spec, bells, out))
        first.start()
        out.get(timeout=20)
        box.put("one")
        assert out.get(timeout=5) == "one"
        time.sleep(0.1)                              # it is blocked in wait() now
        os.kill(first.pid, signal.SIGKILL)
        first.join(5)
        box.put("two")                               # nobody reads it yet
        second = ctx.Process(target=_reader, args=(control.spec, bells, out))
        second.start()
        out.get(timeout=20)
        assert out.get(timeout=5) == "two"           # the waiting message is picked up at start
        box.put("three")
        assert out.get(timeout=5) == "three"
        second.kill()
        second.join(5)
    finally:
        control.close()


def test_a_writer_killed_mid_write_does_not_wedge_the_mailbox():
    ctx = multiprocessing.get_context("spawn")
    control = Control.create(("a",), {"frames": ctx.Semaphore(0)})
    try:
        box = control.mailbox("frames")
        box.put("one")
        box._hdr[0] += 1                  # what a writer SIGKILLed between its two lock bumps leaves: odd
        assert box.take() is None         # a half-written message is never read
        box.put("two")                    # the restarted writer
        assert box.take() == "two" and not box.pending()
        box.put("three")
        assert box.take() == "three"
    finally:
        control.close()


def test_health_board_reset_and_view():
    control = Control.create(("capture", "publisher"), {})
    try:
        board = control.board
        board.reset("capture", 100.0)
        h = board.health("capture")
        assert h.stage == "capture" and h.state == "starting" and h.step_started == 100.0
        row = board.row("capture")
        row.set_state("running")
        row.set("step_started", float("nan"))
        row.add("frames", 3)
        h = board.health("capture")
        assert h.state == "running" and h.step_started is None and h.frames == 3
    finally:
        control.close()
