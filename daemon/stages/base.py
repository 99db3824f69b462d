"""What every stage process shares: setup after spawn, the heartbeat, steps, counters and shutdown.

The supervisor spawns :func:`stage_main` with a picklable :class:`StageArgs`. In the child it

* asks the kernel to send SIGTERM when the supervisor dies (``PR_SET_PDEATHSIG``), ignores SIGINT (a Ctrl-C
  in a terminal reaches the whole process group; the supervisor stops the stages in order) and, on SIGTERM,
  leaves the supervisor ``SIGNAL_GRACE_S`` to stop the stages in order before stopping on its own;
* configures structlog, attaches the control segment (and the frame ring) without registering them with the
  resource tracker, and calls the stage's ``run(rt)``.

A stage loop calls ``rt.beat()`` every turn (at least every 0.2 s), wraps each unit of work in
``with rt.step():`` (the watchdog sees when the step began) and calls ``rt.ready()`` once warmed up.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import math
import os
import signal
import sys
import time
import traceback
from dataclasses import dataclass
from typing import Any

from posed.daemon import clock, logs
from posed.daemon.config import Config
from posed.daemon.proc.control import Control, ControlSpec
from posed.daemon.proc.ring import FrameRing, RingSpec
from posed.daemon.proc.stats import RateMeter, Window

EXIT_FATAL = 78         # the stage cannot work with this config or installation: do not restart
EXIT_FAILED = 1
_PR_SET_PDEATHSIG = 1
SIGNAL_GRACE_S = 2.0


@dataclass(frozen=True)
class StageArgs:
    """Everything a stage process needs (sent once at spawn)."""

    name: str
    entry: str                      # "package.module:function" called with the StageRuntime
    config: Config
    control: ControlSpec
    ring: RingSpec | None
    supervisor_pid: int
    input: str | None = None        # mailbox this stage waits on
    output: str | None = None       # mailbox this stage writes


class StageStop(Exception):
    """Raised inside a stage to leave its loop."""


class StageRuntime:
    """The running stage's view of its health row, mailboxes and ring."""

    STATS_EVERY_S = 0.5

    def __init__(self, args: StageArgs, control: Control, ring: FrameRing | None) -> None:
        self.args = args
        self.name = args.name
        self.config = args.config
        self.control = control
        self.ring = ring
        self.row = control.board.row(args.name)
        self.log = logs.get(args.name, pid=os.getpid())
        self._signalled: float | None = None
        self._steps = Window(256)
        self._latency = Window(256)
        self._rate = RateMeter(2.0)
        self._last_stats = 0.0
        self.row.set("pid", os.getpid())
        self.beat()

    # -- mailboxes -----------------------------------------------------------------------------------
    @property
    def input(self):
        return self.control.mailbox(self.args.input) if self.args.input else None

    @property
    def output(self):
        return self.control.mailbox(self.args.output) if self.args.output else None

    def mailbox(self, name: str):
        return self.control.mailbox(name)

    def send(self, message: Any, lossless: bool = False) -> None:
        """Put ``message`` in the output mailbox; a message the next stage had not taken is a drop.

        ``lossless`` (unpaced replays) first waits until the next stage has taken the previous message, so
        the pipeline runs at the pace of its slowest stage without dropping anything."""
        box = self.output
        if lossless and box.pending():
            step = self.row.get("step_started")
            self.row.set("step_started", float("nan"))     # waiting is not being busy
            self.wait_taken()
            if not math.isnan(step):
                self.row.set("step_started", clock.now())
        if box.put(message):
            self.row.add("drops")

    def wait_taken(self) -> None:
        """Wait (beating, and stopping when asked) until the next stage has taken the last message."""
        while self.output.pending():
            self.beat()
            self.check_stop()
            time.sleep(0.0005)

    def report(self, **info: Any) -> None:
        """Tell the supervisor something (camera info, a fatal error) through this stage's report mailbox."""
        self.control.mailbox(f"report.{self.name}").put(info)

    # -- health --------------------------------------------------------------------------------------
    def beat(self) -> None:
        now = clock.now()
        self.row.set("beat", now)
        if now - self._last_stats >= self.STATS_EVERY_S:
            self._last_stats = now
            self._write_stats(now)

    @property
    def should_stop(self) -> bool:
        """The supervisor asked us to stop, or it is gone, or we got SIGTERM and the supervisor did not
        follow up within SIGNAL_GRACE_S (a SIGTERM to the whole process group reaches the supervisor too,
        which then stops the stages in order)."""
        if self.row.get("stop") > 0 or os.getppid() != self.args.supervisor_pid:
            return True
        return self._signalled is not None and clock.now() - self._signalled > SIGNAL_GRACE_S

    def check_stop(self) -> None:
        if self.should_stop:
            raise StageStop

    def ready(self) -> None:
        """Warm-up finished: from now on the watchdog times single steps."""
        self.row.set("step_started", float("nan"))
        self.row.set_state("running")
        self.row.set("ready", 1.0)
        self.beat()
        self.log.info("stage_ready", warmup_s=round(clock.now() - self.row.get("started"), 2))

    def wait_go(self) -> None:
        """Wait (beating) until the supervisor says every stage is ready."""
        while self.row.get("go") < 1:
            self.beat()
            self.check_stop()
            time.sleep(0.02)

    @contextlib.contextmanager
    def step(self):
        """One unit of work; the watchdog restarts the stage when one lasts longer than stuck_after_s."""
        self.row.set("step_started", clock.now())
        try:
            yield
        finally:
            self.row.set("step_started", float("nan"))
            self.beat()

    def done(self, step_s: float, t_capture: float | None = None, now: float | None = None) -> None:
        """Count a processed frame: its work time and its age since capture at this stage's output."""
        now = clock.now() if now is None else now
        self.row.add("frames")
        self._steps.add(step_s * 1e3)
        if t_capture is not None:
            self._latency.add((now - t_capture) * 1e3)
        self._rate.tick(now)

    def drop(self, n: int = 1) -> None:
        self.row.add("drops", n)

    def skip(self, n: int = 1) -> None:
        self.row.add("skipped", n)

    def error(self, n: int = 1) -> None:
        self.row.add("errors", n)

    def bad_frame(self, n: int = 1) -> None:
        """A frame that could not be used (corrupt, too large) was skipped."""
        self.row.add("bad_frames", n)

    def _write_stats(self, now: float) -> None:
        p50, p95, mx = self._steps.percentiles()
        self.row.set("step_p50_ms", p50)
        self.row.set("step_p95_ms", p95)
        self.row.set("step_max_ms", mx)
        p50, p95, mx = self._latency.percentiles()
        self.row.set("lat_p50_ms", p50)
        self.row.set("lat_p95_ms", p95)
        self.row.set("lat_max_ms", mx)
        self.row.set("fps", self._rate.rate(now))

    def fatal(self, message: str, fix: str = "") -> None:
        """Report a problem restarting cannot cure (missing model, missing file) and leave with 78."""
        self.log.error("stage_fatal", error=message, fix=fix)
        self.report(fatal=message, fix=fix)
        self.row.set_state("fatal")
        raise SystemExit(EXIT_FATAL)

    def _on_signal(self, signum, frame) -> None:
        if self._signalled is None:
            self._signalled = clock.now()


def _set_parent_death_signal() -> None:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def resolve_entry(entry: str):
    module, _, func = entry.partition(":")
    return getattr(importlib.import_module(module), func)


def stage_main(args: StageArgs, doorbells: dict) -> None:
    """Spawn target of every stage process."""
    _set_parent_death_signal()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if os.getppid() != args.supervisor_pid:
        sys.exit(EXIT_FAILED)
    logs.configure(args.config.logging.level, args.config.logging.format, robot=args.config.robot_id)
    control = Control.attach(args.control, doorbells)
    ring = FrameRing.attach(args.ring) if args.ring is not None else None
    rt = StageRuntime(args, control, ring)
    signal.signal(signal.SIGTERM, rt._on_signal)
    code = 0
    try:
        rt.log.info("stage_start", entry=args.entry)
        resolve_entry(args.entry)(rt)
    except StageStop:
        pass
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else EXIT_FAILED
    except Exception as exc:
        rt.row.set_state("failed")
        rt.log.error("stage_failed", error=repr(exc), traceback=traceback.format_exc(limit=8))
        code = EXIT_FAILED
    finally:
        if rt.row.state not in ("fatal", "failed"):
            rt.row.set_state("stopped")
        rt.log.info("stage_exit", code=code)
        if ring is not None:
            ring.close()
        control.close()
        sys.stdout.flush()
    os._exit(code)


def sleep_until(t: float, rt: StageRuntime, slice_s: float = 0.1) -> None:
    """Sleep until monotonic time ``t`` while beating and honouring stop requests."""
    while True:
        rt.beat()
        rt.check_stop()
        left = t - clock.now()
        if left <= 0:
            return
        time.sleep(min(slice_s, left))
