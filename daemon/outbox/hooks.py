"""Hook commands run on each fall event, off the pipeline's thread.

Each configured hook (``hooks.on_event``) has its own worker thread and queue, so a hanging hook delays
neither the pipeline nor the other hooks. A hook is an argv list run without a shell (arguments stay
literal: ``;``, ``$(...)``, quotes and globs mean nothing), in its own session so that a timeout kills it and
every child it started. The event's JSON is on its stdin, and ``POSED_EVENT_*`` environment variables carry
the main fields. A non-zero exit, a timeout or a missing program is retried ``retries`` times with a delay;
stdout and stderr (the first ``output_limit`` bytes) are logged with structlog. The event itself is already
in the journal before a hook sees it, so a failing hook never loses it.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import threading
import time
from dataclasses import dataclass

from daemon import logs
from daemon.config.sections import HookConfig, HooksConfig
from falls.event import FallEvent

_STOP = object()
KEEP_OUTCOMES = 200   # HookRunner.outcomes keeps this many of the latest runs


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
    def __init__(self, index: int, hook: HookConfig, cfg: HooksConfig, outcomes) -> None:
        self.index = index
        self.hook = hook
        self.cfg = cfg
        self.queue: queue.Queue = queue.Queue()
        self._outcomes = outcomes
        self._stopping = threading.Event()
        self.log = logs.get("hooks", hook=index, program=hook.argv[0] if hook.argv else "")
        self.thread = threading.Thread(target=self._loop, name=f"posed-hook-{index}", daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        while True:
            item = self.queue.get()
            if item is _STOP:
                self.queue.task_done()
                return
            try:
                self._deliver(item)
            except Exception as exc:  # a bug here must not kill the worker
                self.log.error("hook_worker_error", error=repr(exc), event_id=item.id)
            finally:
                self.queue.task_done()

    def _deliver(self, event: FallEvent) -> None:
        attempts = 1 + self.hook.retries
        for attempt in range(1, attempts + 1):
            if self._stopping.is_set() and attempt > 1:
                self.log.warning("hook_abandoned_at_shutdown", event_id=event.id, state=event.state)
                return
            outcome = self._run_once(event, attempt)
            self._outcomes(outcome)
            fields = dict(event_id=event.id, state=event.state, attempt=attempt, of=attempts,
                          returncode=outcome.returncode, seconds=round(outcome.seconds, 3))
            if outcome.stdout:
                fields["stdout"] = outcome.stdout
            if outcome.stderr:
                fields["stderr"] = outcome.stderr
            if outcome.ok:
                self.log.info("hook_done", **fields)
                return
            if outcome.timed_out:
                self.log.warning("hook_timeout", timeout_s=self.hook.timeout_s,
                                 fix=f"the hook ran longer than hooks.on_event[{self.index}].timeout_s and was "
                                     "killed; make it faster or raise timeout_s", **fields)
            elif outcome.error:
                self.log.warning("hook_failed", error=outcome.error, **fields)
            else:
                self.log.warning("hook_failed", error=f"exit status {outcome.returncode}", **fields)
            if attempt < attempts:
                self._stopping.wait(self.cfg.retry_delay_s * attempt)
        self.log.error("hook_gave_up", event_id=event.id, state=event.state, attempts=attempts,
                       note="the event is kept in the journal")

    def _run_once(self, event: FallEvent, attempt: int) -> HookOutcome:
        limit = self.cfg.output_limit
        env = dict(os.environ)
        env.update(event_environment(event))
        env["POSED_HOOK_ATTEMPT"] = str(attempt)
        payload = json.dumps(event.to_json()).encode()
        t0 = time.monotonic()

        def outcome(ok, rc, timed_out, error, out=b"", err=b""):
            return HookOutcome(self.index, event.id, event.state, attempt, ok, rc, timed_out, error,
                               out[:limit].decode("utf-8", "replace"), err[:limit].decode("utf-8", "replace"),
                               time.monotonic() - t0)

        if not self.hook.argv:
            return outcome(False, None, False, f"hooks.on_event[{self.index}].argv is empty; give a program "
                                               "and its arguments as a list")
        try:
            proc = subprocess.Popen(list(self.hook.argv), stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, env=env, start_new_session=True, close_fds=True)
        except OSError as exc:
            return outcome(False, None, False,
                           f"cannot start {self.hook.argv[0]!r}: {exc.strerror or exc}; fix "
                           f"hooks.on_event[{self.index}].argv[0] (an absolute path to an executable)")
        try:
            out, err = proc.communicate(payload, timeout=self.hook.timeout_s)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            try:
                out, err = proc.communicate(timeout=2.0)
            except subprocess.TimeoutExpired:
                out, err = b"", b""
            return outcome(False, proc.returncode, True, "timeout", out or b"", err or b"")
        except BrokenPipeError:  # the hook exited without reading stdin: not an error in itself
            out, err = proc.communicate()
        return outcome(proc.returncode == 0, proc.returncode, False, "", out or b"", err or b"")


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        try:
            proc.kill()
        except ProcessLookupError:
            pass


class HookRunner:
    """Runs ``cfg.on_event`` hooks for each submitted event; ``submit`` returns at once."""

    def __init__(self, cfg: HooksConfig) -> None:
        self.cfg = cfg
        self._lock = threading.Lock()
        self.outcomes: list[HookOutcome] = []  # the last KEEP_OUTCOMES runs, newest last
        self._workers = [_Worker(i, h, cfg, self._record) for i, h in enumerate(cfg.on_event)]
        self._closed = False

    def _record(self, outcome: HookOutcome) -> None:
        with self._lock:
            self.outcomes.append(outcome)
            del self.outcomes[: max(0, len(self.outcomes) - KEEP_OUTCOMES)]

    def submit(self, event: FallEvent) -> None:
        """Queue the event for every hook; never blocks, never raises."""
        if self._closed:
            return
        for worker in self._workers:
            worker.queue.put(event)

    def pending(self) -> int:
        """Events queued or running, summed over the hooks."""
        return sum(w.queue.unfinished_tasks for w in self._workers)

    def wait_idle(self, timeout: float) -> bool:
        """Wait until every queued event has been handled; True if so before ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.pending() == 0:
                return True
            time.sleep(0.02)
        return self.pending() == 0

    def close(self, timeout: float = 5.0) -> None:
        """Stop the workers: queued events still run for up to ``timeout`` seconds, no new retries start."""
        self._closed = True
        for worker in self._workers:
            worker.queue.put(_STOP)
        deadline = time.monotonic() + timeout
        for worker in self._workers:
            worker.thread.join(max(0.0, deadline - time.monotonic()))
            if worker.thread.is_alive():
                worker._stopping.set()
                worker.log.warning("hook_still_running_at_shutdown", queued=worker.queue.qsize())

    def __enter__(self) -> HookRunner:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
