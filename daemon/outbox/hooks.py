"""Hook commands run on each fall event, off the pipeline's thread.

Each configured hook (``hooks.on_event``) has its own worker thread and queue, so a hanging hook delays
neither the pipeline nor the other hooks. A hook is an argv list run without a shell (arguments stay
literal: ``;``, ``$(...)``, quotes and globs mean nothing), in its own session (its own process group) so
that a timeout kills it and every child it started. The event's JSON is on its stdin, and ``POSED_EVENT_*``
environment variables carry the main fields. A non-zero exit, a timeout or a missing program is retried
``retries`` times with a delay. The event itself is already in the journal before a hook sees it.

Delivery is at least once. The runner tells its ``listener`` (:class:`daemon.outbox.delivery.EventOutbox`,
which writes it to the journal) before each run starts and when a hook is done with a message: ``ok``,
``gave_up`` (failed after its retries), or ``pending`` (not done: cut off or not started because the daemon
stopped, or dropped from a full queue). A message that is not done by every hook — also when the publisher is
killed -9 in the middle of a run — is handed to the hooks again at the next start (``submit(..., attempts=...,
redelivered=True)``), so a hook may see a message more than once: ``POSED_EVENT_ID`` and
``POSED_EVENT_STATE`` identify it, ``POSED_HOOK_ATTEMPT`` counts the runs of this hook for this message
across restarts (1: the first run ever) and ``POSED_HOOK_REDELIVERED`` is 1 when the journal handed it again
at a start.

Bounds, whatever a hook does:

* output: the first ``output_limit`` bytes of stdout and of stderr are kept (and logged); the rest is read
  and discarded as it comes, so a hook printing hundreds of megabytes costs no memory;
* the queue: at most ``queue_limit`` events wait for each hook; when it is full the oldest waiting one is
  dropped (``dropped``, logged with a rate limit) and ``submit`` never blocks;
* shutdown (:meth:`HookRunner.close`, on SIGTERM of the daemon with or without systemd): no new run or retry
  starts (what waits stays pending for the next start), running hooks get the close timeout, then their
  process groups get SIGTERM and, after ``TERM_GRACE_S``, SIGKILL (a run cut off so is not done either);
* a publisher that dies without closing (kill -9): every hook carries ``POSED_HOOK_OWNER`` (supervisor and
  publisher pids) in its environment, and the supervisor ends what the dead publisher left
  (:mod:`daemon.proc.orphans`) before it starts a new one.
"""

from __future__ import annotations

import hashlib
import json
import os
import selectors
import signal
import subprocess
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from posed.daemon import logs
from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.proc import orphans
from posed.daemon.proc.throttle import Throttle
from posed.falls.event import FallEvent

KEEP_OUTCOMES = 200   # HookRunner.outcomes keeps this many of the latest runs
TERM_GRACE_S = 1.0    # at shutdown: SIGTERM to a hook's process group, SIGKILL this much later
READ_CHUNK = 65536
EXIT_GRACE_S = 1.0    # after the hook exited, how long its children may keep its output pipes open


def hook_key(argv: Sequence[str], earlier: Sequence[str] = ()) -> str:
    """What the journal knows a hook by (``hook_runs.hook``): a hash of its argv, so a hook keeps its key when
    the others change and a hook given other arguments is a new one; ``#2``, ``#3`` ... for a second or third
    hook with the same argv (``earlier``: the keys of the hooks before it)."""
    key = hashlib.sha256(json.dumps(list(argv)).encode()).hexdigest()[:16]
    n = sum(1 for k in earlier if k.split("#")[0] == key)
    return key if n == 0 else f"{key}#{n + 1}"


class HookListener(Protocol):
    """Told about each hook's progress with each message (called on the hook's worker thread)."""

    def hook_starting(self, event: FallEvent, hook: int, attempt: int) -> None:
        """Run ``attempt`` of hook ``hook`` (its index in ``hooks.on_event``) is about to start."""

    def hook_ended(self, event: FallEvent, hook: int, outcome: str) -> None:
        """Hook ``hook`` is through with the message for now: ``ok``, ``gave_up`` or ``pending`` (not done)."""


@dataclass(frozen=True)
class _Job:
    """One message for one hook: ``first_attempt`` numbers its first run (runs started before a restart count),
    ``redelivered``: handed again from the journal at a start."""

    event: FallEvent
    first_attempt: int = 1
    redelivered: bool = False


def event_environment(event: FallEvent) -> dict[str, str]:
    """The ``POSED_EVENT_*`` variables a hook receives (empty string for an unknown time)."""

    def num(v: float | None) -> str:
        return "" if v is None else repr(float(v))

    return {
        "POSED_EVENT_ID": event.id,
        "POSED_EVENT_ROBOT": event.robot,
        "POSED_EVENT_STATE": event.state,
        "POSED_EVENT_T_ONSET": num(event.t_onset),
        "POSED_EVENT_T_IMPACT": num(event.t_impact),
        "POSED_EVENT_T_DETECT": num(event.t_detect),
        "POSED_EVENT_CONFIDENCE": f"{event.confidence:.3f}",
        "POSED_EVENT_FEATURES": ",".join(event.features),
        "POSED_EVENT_WALL_TIME": event.wall_time,
    }


@dataclass(frozen=True)
class HookOutcome:
    """What one run of one hook did (for logs and tests)."""

    hook: int
    event_id: str
    state: str
    attempt: int
    ok: bool
    returncode: int | None
    timed_out: bool
    error: str
    stdout: str
    stderr: str
    seconds: float


class _Worker:
    """One hook's queue, thread and the process it is running."""

    def __init__(self, index: int, hook: HookConfig, cfg: HooksConfig, outcomes, throttle: Throttle,
                 notify) -> None:
        self.index = index
        self.hook = hook
        self.cfg = cfg
        self.dropped = 0
        self._notify = notify                  # (what, event, index, value): the runner's listener, if any
        self._events: deque[_Job] = deque()
        self._cond = threading.Condition()
        self._busy = False
        self._proc: subprocess.Popen | None = None
        self._proc_lock = threading.Lock()     # the running process (not _cond: submit never waits on a fork)
        self._outcomes = outcomes
        self._throttle = throttle
        self._stopping = threading.Event()
        self.log = logs.get("hooks", hook=index, program=hook.argv[0] if hook.argv else "")
        self.thread = threading.Thread(target=self._loop, name=f"posed-hook-{index}", daemon=True)
        self.thread.start()

    # ---------------------------------------------------------------- the queue
    def put(self, job: _Job) -> None:
        old = None
        with self._cond:
            if self._stopping.is_set():
                return
            if len(self._events) >= self.cfg.queue_limit:
                old = self._drop_oldest().event
                self.dropped += 1
                suppressed = self._throttle.allow(f"queue_full.{self.index}")
                if suppressed is not None:
                    self.log.warning("hook_queue_full", dropped_event=old.id, dropped_state=old.state,
                                     dropped=self.dropped, queue_limit=self.cfg.queue_limit, suppressed=suppressed,
                                     note="the hook is slower than the events; the oldest waiting event was "
                                          "dropped (it stays in the journal, pending: handed to the hook again "
                                          "at the next start)")
            self._enqueue(job)
            self._cond.notify()
        if old is not None:
            self._notify("ended", old, self.index, "pending")

    def _enqueue(self, job: _Job) -> None:
        """A new message goes before the messages handed again from the journal (a fall now is not phoned in
        after the backlog of the run before); otherwise in order."""
        if job.redelivered:
            self._events.append(job)
            return
        first_old = next((i for i, queued in enumerate(self._events) if queued.redelivered), None)
        if first_old is None:
            self._events.append(job)
        else:
            self._events.insert(first_old, job)

    def _drop_oldest(self) -> _Job:
        """The queue is full: the oldest message handed again from the journal leaves it, else the oldest."""
        old = next((queued for queued in self._events if queued.redelivered), None)
        if old is None:
            return self._events.popleft()
        self._events.remove(old)
        return old

    def pending(self) -> int:
        with self._cond:
            return len(self._events) + int(self._busy)

    def running(self) -> int:
        with self._proc_lock:
            return int(self._proc is not None)

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._events and not self._stopping.is_set():
                    self._cond.wait()
                if self._stopping.is_set():
                    return
                job = self._events.popleft()
                self._busy = True
            try:
                self._deliver(job)
            except Exception as exc:  # a bug here must not kill the worker
                self.log.error("hook_worker_error", error=repr(exc), event_id=job.event.id)
            finally:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()

    # ---------------------------------------------------------------- shutdown
    def stop(self) -> list[FallEvent]:
        """No new run or retry from now on; returns the queued messages that will not run (pending)."""
        with self._cond:
            self._stopping.set()
            left = [job.event for job in self._events]
            self._events.clear()
            self._cond.notify_all()
        return left

    def end_process(self) -> None:
        """SIGTERM to the running hook's process group, SIGKILL after TERM_GRACE_S."""
        with self._proc_lock:
            proc = self._proc
        if proc is None:
            return
        self.log.warning("hook_ended_at_shutdown", hook_pid=proc.pid, grace_s=TERM_GRACE_S,
                         note="the run was cut off: its message stays pending in the journal and is handed to "
                              "the hook again at the next start")
        signal_group(proc, signal.SIGTERM)
        try:
            proc.wait(TERM_GRACE_S)
        except subprocess.TimeoutExpired:
            pass
        signal_group(proc, signal.SIGKILL)     # the leader may have left children in its group

    # ---------------------------------------------------------------- one event
    def _deliver(self, job: _Job) -> None:
        event = job.event
        attempts = 1 + self.hook.retries
        last = job.first_attempt + attempts - 1
        for n in range(1, attempts + 1):
            attempt = job.first_attempt + n - 1
            if self._stopping.is_set():
                if n > 1:
                    self.log.warning("hook_retry_pending_at_shutdown", event_id=event.id, state=event.state,
                                     attempts_made=attempt - 1,
                                     note="no retry starts once shutdown began: the message stays pending in "
                                          "the journal and is handed to the hook again at the next start")
                self._notify("ended", event, self.index, "pending")
                return
            self._notify("starting", event, self.index, attempt)
            outcome = self._run_once(event, attempt, job.redelivered)
            self._outcomes(outcome)
            fields = dict(event_id=event.id, state=event.state, attempt=attempt, of=last,
                          returncode=outcome.returncode, seconds=round(outcome.seconds, 3))
            if job.redelivered:
                fields["redelivered"] = True
            if outcome.stdout:
                fields["stdout"] = outcome.stdout
            if outcome.stderr:
                fields["stderr"] = outcome.stderr
            if outcome.ok:
                self.log.info("hook_done", **fields)
                self._notify("ended", event, self.index, "ok")
                return
            if self._stopping.is_set():          # cut off (or failed) while the daemon stops: not done
                self.log.warning("hook_cut_off_at_shutdown", error=outcome.error or f"exit status {outcome.returncode}",
                                 note="the message stays pending in the journal and is handed to the hook again "
                                      "at the next start", **fields)
                self._notify("ended", event, self.index, "pending")
                return
            if outcome.timed_out:
                self.log.warning("hook_timeout", timeout_s=self.hook.timeout_s,
                                 fix=f"the hook ran longer than hooks.on_event[{self.index}].timeout_s and was "
                                     "killed; make it faster or raise timeout_s", **fields)
            elif outcome.error:
                self.log.warning("hook_failed", error=outcome.error, **fields)
            else:
                self.log.warning("hook_failed", error=f"exit status {outcome.returncode}", **fields)
            if n < attempts:
                self._stopping.wait(self.cfg.retry_delay_s * n)
        self.log.error("hook_gave_up", event_id=event.id, state=event.state, attempts=attempts,
                       note="the event stays in the journal (republished until acknowledged); this hook will not "
                            "run for it again")
        self._notify("ended", event, self.index, "gave_up")

    def _run_once(self, event: FallEvent, attempt: int, redelivered: bool = False) -> HookOutcome:
        limit = self.cfg.output_limit
        env = dict(os.environ)
        env.update(event_environment(event))
        env["POSED_HOOK_ATTEMPT"] = str(attempt)
        env["POSED_HOOK_REDELIVERED"] = "1" if redelivered else "0"
        # lets the supervisor end this hook and its children if this process dies without closing (kill -9)
        env[orphans.OWNER_ENV] = orphans.owner_tag(os.getppid(), os.getpid())
        payload = json.dumps(event.to_json()).encode()
        t0 = time.monotonic()

        def outcome(ok, rc, timed_out, error, out=b"", err=b""):
            return HookOutcome(self.index, event.id, event.state, attempt, ok, rc, timed_out, error,
                               out[:limit].decode("utf-8", "replace"), err[:limit].decode("utf-8", "replace"),
                               time.monotonic() - t0)

        if not self.hook.argv:
            return outcome(False, None, False, f"hooks.on_event[{self.index}].argv is empty; give a program "
                                               "and its arguments as a list")
        with self._proc_lock:
            if self._stopping.is_set():
                return outcome(False, None, False, "not started: the daemon is stopping")
            try:
                proc = start_program(self.hook.argv, env)
            except OSError as exc:
                return outcome(False, None, False, cannot_start(self.hook.argv, exc, f"hooks.on_event[{self.index}]"))
            self._proc = proc
        try:
            rc, timed_out, out, err = finish_program(proc, payload, limit, self.hook.timeout_s)
        finally:
            with self._proc_lock:
                self._proc = None
        if timed_out:
            return outcome(False, rc, True, "timeout", out, err)
        return outcome(rc == 0, rc, False, "", out, err)


def start_program(argv: Sequence[str], env: dict[str, str]) -> subprocess.Popen:
    """A hook's program started without a shell, in a session of its own (a timeout kills it and its children),
    its stdin, stdout and stderr piped; raises OSError when it cannot start."""
    return subprocess.Popen(list(argv), stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=env, start_new_session=True, close_fds=True)


def cannot_start(argv: Sequence[str], exc: OSError, where: str) -> str:
    """Why a hook's program did not start, and the key to fix (``where``: ``hooks.on_event[0]``)."""
    return (f"cannot start {argv[0]!r}: {exc.strerror or exc}; fix {where}.argv[0] (an absolute path to an "
            "executable)")


def finish_program(proc: subprocess.Popen, payload: bytes, limit: int,
                   timeout_s: float) -> tuple[int, bool, bytes, bytes]:
    """``payload`` to a started hook, its output read (:func:`exchange`), its process group killed after
    ``timeout_s``; (return code, timed out, stdout, stderr)."""
    out, err, timed_out = exchange(proc, payload, limit, timeout_s)
    if timed_out:
        signal_group(proc, signal.SIGKILL)
    return proc.wait(), timed_out, out, err


def exchange(proc: subprocess.Popen, payload: bytes, limit: int, timeout_s: float) -> tuple[bytes, bytes, bool]:
    """Write ``payload`` to the hook's stdin and read its stdout and stderr until they close, keeping the
    first ``limit`` bytes of each and discarding the rest. Returns (stdout, stderr, timed out)."""
    deadline = time.monotonic() + timeout_s
    out_fd, err_fd = proc.stdout.fileno(), proc.stderr.fileno()
    kept = {out_fd: bytearray(), err_fd: bytearray()}
    exited_at: float | None = None
    timed_out = False
    view = memoryview(payload)
    with selectors.DefaultSelector() as sel:
        for fd in kept:
            sel.register(fd, selectors.EVENT_READ)
        if view:
            os.set_blocking(proc.stdin.fileno(), False)
            sel.register(proc.stdin.fileno(), selectors.EVENT_WRITE)
        else:
            proc.stdin.close()
        while sel.get_map():
            now = time.monotonic()
            if now >= deadline:
                timed_out = True
                break
            if exited_at is None and proc.poll() is not None:
                exited_at = now
            if exited_at is not None and now - exited_at > EXIT_GRACE_S:
                break                       # the hook is gone; a child of it holds the pipes open
            for key, _ in sel.select(min(0.2, deadline - now)):
                fd = key.fd
                if fd in kept:
                    chunk = os.read(fd, READ_CHUNK)
                    if not chunk:
                        sel.unregister(fd)
                    elif len(kept[fd]) < limit:
                        kept[fd] += chunk[: limit - len(kept[fd])]
                    continue
                try:
                    view = view[os.write(fd, view[:READ_CHUNK]):]
                except OSError:             # BrokenPipeError: the hook exited without reading stdin (fine)
                    view = view[:0]
                if not view:
                    sel.unregister(fd)
                    proc.stdin.close()
    _close_pipes(proc)
    return bytes(kept[out_fd]), bytes(kept[err_fd]), timed_out


def _close_pipes(proc: subprocess.Popen) -> None:
    for f in (proc.stdin, proc.stdout, proc.stderr):
        try:
            f.close()
        except (OSError, ValueError):
            pass


def signal_group(proc: subprocess.Popen, sig: int) -> None:
    """``sig`` to the hook's process group (its pid: it leads its own session), or to the hook alone."""
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        try:
            proc.send_signal(sig)
        except (ProcessLookupError, OSError):
            pass


class HookRunner:
    """Runs ``cfg.on_event`` hooks for each submitted event; ``submit`` returns at once.

    ``keys``: each hook's key (:func:`hook_key`), in ``cfg.on_event`` order. ``listener``
    (:class:`HookListener`, set by whoever keeps track, e.g. the outbox) hears of every run and outcome."""

    def __init__(self, cfg: HooksConfig) -> None:
        self.cfg = cfg
        self._lock = threading.Lock()
        self.outcomes: list[HookOutcome] = []  # the last KEEP_OUTCOMES runs, newest last
        self.listener: HookListener | None = None
        keys: list[str] = []
        for h in cfg.on_event:
            keys.append(hook_key(h.argv, keys))
        self.keys: tuple[str, ...] = tuple(keys)
        self._log = logs.get("hooks")
        throttle = Throttle()
        self._workers = [_Worker(i, h, cfg, self._record, throttle, self._notify) for i, h in enumerate(cfg.on_event)]
        self._closed = False

    def _notify(self, what: str, event: FallEvent, index: int, value) -> None:
        listener = self.listener
        if listener is None:
            return
        try:
            if what == "starting":
                listener.hook_starting(event, index, value)
            else:
                listener.hook_ended(event, index, value)
        except Exception as exc:   # the journal's trouble is logged there; a bug here must not stop the hook
            self._log.error("hook_listener_error", error=repr(exc), event_id=event.id, state=event.state, hook=index)

    def _record(self, outcome: HookOutcome) -> None:
        with self._lock:
            self.outcomes.append(outcome)
            del self.outcomes[: max(0, len(self.outcomes) - KEEP_OUTCOMES)]

    def submit(self, event: FallEvent, attempts: dict[int, int] | None = None, redelivered: bool = False) -> None:
        """Queue the event for every hook, or for the hooks in ``attempts`` (hook index -> the number of its
        first run: runs already started before a restart count); never blocks, never raises (a full queue drops
        its oldest, a redelivered one first). ``redelivered``: handed again from the journal at a start; a new
        message runs before those."""
        if self._closed:
            return
        for worker in self._workers:
            if attempts is None:
                worker.put(_Job(event, 1, redelivered))
            elif worker.index in attempts:
                worker.put(_Job(event, max(1, attempts[worker.index]), redelivered))

    @property
    def dropped(self) -> int:
        """Events dropped from full queues, summed over the hooks."""
        return sum(w.dropped for w in self._workers)

    def pending(self) -> int:
        """Events queued or running, summed over the hooks."""
        return sum(w.pending() for w in self._workers)

    def running(self) -> int:
        """Hook processes running now."""
        return sum(w.running() for w in self._workers)

    def pids(self) -> set[int]:
        """The hook processes this runner started and still waits for."""
        return {p.pid for p in (w._proc for w in self._workers) if p is not None}

    def wait_idle(self, timeout: float) -> bool:
        """Wait until every queued event has been handled; True if so before ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.pending() == 0:
                return True
            time.sleep(0.02)
        return self.pending() == 0

    def close(self, timeout: float = 5.0) -> None:
        """Stop: no new run or retry starts (queued messages stay pending in the journal, for the next start);
        running hooks get ``timeout`` seconds, then SIGTERM to their process groups and SIGKILL TERM_GRACE_S
        later (a run cut off so is not done either)."""
        self._closed = True
        for worker in self._workers:
            left = worker.stop()
            if left:
                worker.log.warning("hooks_pending_at_shutdown", queued=len(left),
                                   messages=[f"{e.id}:{e.state}" for e in left[:20]],
                                   note="not run now: they stay pending in the journal and are handed to the "
                                        "hook again at the next start")
                for event in left:
                    self._notify("ended", event, worker.index, "pending")
        deadline = time.monotonic() + timeout
        for worker in self._workers:
            worker.thread.join(max(0.0, deadline - time.monotonic()))
        for worker in self._workers:
            if worker.thread.is_alive():
                worker.end_process()
        for worker in self._workers:
            worker.thread.join(2.0)

    def __enter__(self) -> HookRunner:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
