"""Hooks run when posed stops watching, and when it watches again (``hooks.on_watch_lost``).

A fall monitor that cannot see cannot raise an alarm, and the carer who relies on the alarm hook would hear
nothing either way. The status says why posed is not watching (:data:`NOT_WATCHING`: ``blind``, no frame
gets through; ``waiting_for_camera``, unplugged or a wrong device; ``degraded``, a stage failing;
``escalated``, too many restarts; ``paused``, for privacy on purpose; or the camera ``lost`` or ``ended``). Once that has lasted
``hooks.watch_lost_after_s`` (:class:`WatchLoss`), each hook runs once with ``POSED_WATCH=lost``; when posed
watches again (``running`` with the camera open), once more with ``POSED_WATCH=back``. ``starting`` and
``stopping`` change nothing: a start is judged once it is done, a stop is someone's decision.

A hook runs as a fall hook does (:mod:`daemon.outbox.hooks`): an argv list without a shell, in its own
session, ``timeout_s`` then killed with its children, ``retries`` with ``retry_delay_s`` times n between
them, the first ``output_limit`` bytes of its output logged. Its stdin is the notice's JSON
(:meth:`WatchNotice.to_json`); ``POSED_WATCH`` (``lost`` / ``back``), ``POSED_WATCH_REASON``,
``POSED_WATCH_SINCE_UNIX``, ``POSED_ROBOT`` and ``POSED_HOOK_ATTEMPT`` carry the main fields. Notices are not
journalled: they are about the present, and a daemon started again judges it afresh (still not watching:
``lost`` again after ``watch_lost_after_s``). A flapping camera is one loss (:class:`WatchLoss`): ``back``
comes once posed has watched for ``watch_lost_after_s`` without a break. The same judgement (:func:`judge`)
is published in every status as ``watch`` (:meth:`WatchLoss.state`: watching or not, since when, why), so a
reader never judges it again from the state and the camera. What this cannot tell: a daemon that
is gone altogether (no process left to run a hook); Zenoh's liveliness token ``posed/ROBOT/alive`` and systemd
say that (docs/daemon.md).
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import threading
from dataclasses import dataclass

from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.outbox.hooks import cannot_start, finish_program, signal_group, start_program
from posed.daemon.proc import orphans

NOT_WATCHING = ("blind", "waiting_for_camera", "degraded", "escalated")
CAMERA_GONE = ("lost", "ended")
UNDECIDED = ("starting", "stopping")


@dataclass(frozen=True)
class WatchNotice:
    """posed stopped watching (``watching`` False) or watches again (True); times in unix seconds."""

    watching: bool
    robot: str
    reason: str          # the status's state and what it said (the blind reason, the camera's error)
    since_unix: float    # when posed stopped watching
    time_unix: float     # when this notice was made

    def to_json(self) -> dict:
        return {"format": "posed.watch", "version": 1, "robot": self.robot,
                "watch": "back" if self.watching else "lost", "reason": self.reason,
                "since_unix": round(self.since_unix, 3), "time_unix": round(self.time_unix, 3),
                "not_watching_s": round(self.time_unix - self.since_unix, 1)}

    def environment(self) -> dict[str, str]:
        return {"POSED_WATCH": "back" if self.watching else "lost", "POSED_WATCH_REASON": self.reason,
                "POSED_WATCH_SINCE_UNIX": repr(round(self.since_unix, 3)), "POSED_ROBOT": self.robot}


def judge(status: dict) -> tuple[str, str] | str | None:
    """Whether the status says posed is watching (the one rule of the hooks and of the status's ``watch``):
    None when it watches; ``(reason, detail)`` when it does not (``reason`` the state — blind,
    waiting_for_camera, degraded, escalated, paused (for privacy) — or ``camera lost`` / ``camera ended``; ``detail`` what the status
    said: the blind reason, the camera's error, or ``""``); ``""`` for ``UNDECIDED`` states (keep the current
    judgement)."""
    state = status.get("state")
    camera = status.get("camera") or {}
    if state in UNDECIDED:
        return ""
    if state == "paused":
        return "paused", paused_detail(status.get("privacy") or {})
    if state in NOT_WATCHING:
        blind = status.get("blind") or {}
        return str(state), blind.get("reason") or camera.get("error") or ""
    if camera.get("state") in CAMERA_GONE:
        return f"camera {camera['state']}", camera.get("error") or ""
    return None


def paused_detail(privacy: dict) -> str:
    """``paused for privacy by voice until 2026-12-07T15:42:00+01:00`` (the end in the robot's zone, ISO 8601)."""
    from posed.daemon.timeparse import clock_text, local_zone

    by = privacy.get("by")
    until = privacy.get("until_unix")
    text = "paused for privacy" + (f" by {by}" if by else "")
    return text + (f" until {clock_text(float(until), local_zone())}" if until is not None else "")


def why_not_watching(status: dict) -> str | None:
    """Why the status says posed is not watching (its state and reason), None when it watches; ``UNDECIDED``
    states give ``""`` (keep the current judgement)."""
    return _why(judge(status))


def _why(judged) -> str | None:
    if judged is None or judged == "":
        return judged
    reason, detail = judged
    return f"{reason}: {detail}" if detail else reason


class WatchLoss:
    """Says when posed has not been watching for ``after_s`` seconds (once), and when it watches again after
    that (once). ``update`` takes each status object with the monotonic and unix times it was read at.

    A camera that flaps (lost, back, lost ...) is one loss, not many: the time not watching adds up over short
    returns, and a loss ends only once posed has watched for ``after_s`` without a break. So a camera lost 50 s
    of every 100 s is said (before: never, each loss shorter than the delay), and one lost 70 s of every 80 s
    is said once, ``back`` once it is steady (before: a ``lost`` and a ``back`` every 80 s, the carer called
    90 times an hour); routine hiccups of a few seconds, far apart, still call nobody."""

    def __init__(self, robot: str, after_s: float) -> None:
        self.robot = robot
        self.after_s = after_s
        self._since: tuple[float, float] | None = None      # (monotonic, unix) when this loss began
        self._not_watching_s = 0.0                          # time not watching in this loss, short returns left out
        self._last: tuple[float, bool] | None = None        # (monotonic, watching) of the last judgement
        self._watching_since: float | None = None           # monotonic; None while not watching
        self._reason = ""
        self._told = False
        # the status's ``watch`` (:meth:`state`): watching, since (unix), reason, detail; None before a judgement
        self._state: tuple[bool, float, str | None, str | None] | None = None

    @property
    def lost(self) -> bool:
        """A ``lost`` notice was given and no ``back`` since."""
        return self._told

    def state(self) -> dict | None:
        """The status's ``watch``: ``{"watching", "since_unix" (since when posed has been in this state, watching
        or not), "reason" (why not: the state or ``camera lost``/``ended``; None while watching), "detail" (what
        the status said: the blind reason, the camera's error; None while watching)}``. The judgement is the
        hooks' (:func:`judge`): ``starting`` and ``stopping`` keep the one before them, so a daemon still
        starting has none yet: None (the status's ``state`` says ``starting``). A flapping camera's short
        returns are said as they happen here (``since_unix`` is the latest change); the hooks add them up."""
        if self._state is None:
            return None
        watching, since, reason, detail = self._state
        return {"watching": watching, "since_unix": round(since, 4), "reason": reason, "detail": detail}

    def _judged(self, judged, now_unix: float) -> None:
        if judged == "":
            return
        watching = judged is None
        reason, detail = (None, None) if watching else judged
        if self._state is None or self._state[0] != watching:
            self._state = (watching, now_unix, reason, detail or None)
        else:
            self._state = (watching, self._state[1], reason, detail or None)

    def update(self, status: dict, now: float, now_unix: float) -> WatchNotice | None:
        judged = judge(status)
        self._judged(judged, now_unix)
        why = _why(judged)
        if self._last is not None and not self._last[1]:
            self._not_watching_s += max(0.0, now - self._last[0])
        if why == "":                                   # undecided: the current judgement goes on
            if self._last is not None:
                self._last = (now, self._last[1])
            return None
        watching = why is None
        self._last = (now, watching)
        if watching:
            return self._watching(now, now_unix)
        self._watching_since = None
        if self._since is None:
            self._since, self._not_watching_s = (now, now_unix), 0.0
        self._reason = why
        if not self._told and self._not_watching_s >= self.after_s - 1e-9:
            self._told = True
            return WatchNotice(False, self.robot, why, self._since[1], now_unix)
        return None

    def _watching(self, now: float, now_unix: float) -> WatchNotice | None:
        if self._watching_since is None:
            self._watching_since = now
        if self._since is None or now - self._watching_since < self.after_s - 1e-9:
            return None
        notice = WatchNotice(True, self.robot, self._reason, self._since[1], now_unix) if self._told else None
        self._since, self._told, self._reason, self._not_watching_s = None, False, "", 0.0
        return notice


class WatchHooks:
    """Runs a list of hooks for each notice, in order, on one thread of its own (``submit`` returns at once; a
    notice that finds the queue full is dropped and logged: the next one says the current state). A notice is
    anything with ``to_json()`` (the hook's stdin) and ``environment()`` (its ``POSED_*`` variables).

    By default the hooks are ``cfg.on_watch_lost`` (:class:`WatchNotice`), logged as ``watch_hook_*`` with the
    notice's ``watch``; ``hooks``, ``key``, ``log_as`` and ``field`` run another list the same way, e.g.
    ``hooks.on_absent`` (:class:`daemon.history.absence.AbsenceNotice`: ``absent_hook_*``, ``absence``)."""

    QUEUE = 8

    def __init__(self, cfg: HooksConfig, log, hooks: tuple[HookConfig, ...] | None = None,
                 key: str = "on_watch_lost", log_as: str = "watch_hook", field: str = "watch") -> None:
        self.cfg = cfg
        self.log = log
        self.hooks = tuple(cfg.on_watch_lost if hooks is None else hooks)
        self.key = key              # the config key, in messages: hooks.KEY[i]
        self.log_as = log_as        # log event prefix: LOG_AS_done, _failed, _gave_up, _dropped
        self.field = field          # the notice's to_json() field the log names it by
        self._queue: queue.Queue = queue.Queue(self.QUEUE)
        self._stopping = threading.Event()
        self._proc: subprocess.Popen | None = None
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, name=f"{log_as.replace('_', '-')}s", daemon=True)
        self._thread.start()

    def _what(self, notice) -> dict:
        return {self.field: notice.to_json().get(self.field)}

    def submit(self, notice) -> None:
        try:
            self._queue.put_nowait(notice)
        except queue.Full:
            self.log.warning(f"{self.log_as}_dropped", **self._what(notice),
                             note=f"the hooks.{self.key} hooks are still busy with earlier notices")

    def close(self, timeout: float = 1.0) -> None:
        """What is queued and running gets ``timeout`` s; then no run starts any more and a running hook's process
        group is killed."""
        try:
            self._queue.put(None, timeout=timeout)
        except queue.Full:
            pass
        self._thread.join(timeout)
        self._stopping.set()
        with self._lock:
            proc = self._proc
        if proc is not None:
            signal_group(proc, signal.SIGKILL)
        self._thread.join(1.0)

    def _loop(self) -> None:
        while not self._stopping.is_set():
            notice = self._queue.get()
            if notice is None:
                return
            for index, hook in enumerate(self.hooks):
                self._deliver(index, hook, notice)

    def _deliver(self, index: int, hook: HookConfig, notice) -> None:
        attempts = 1 + hook.retries
        what = self._what(notice)
        for n in range(1, attempts + 1):
            if self._stopping.is_set():
                return
            rc, timed_out, error, out, err = self._run_once(index, hook, notice, n)
            fields = dict(hook=index, **what, attempt=n, of=attempts, returncode=rc)
            if out:
                fields["stdout"] = out
            if err:
                fields["stderr"] = err
            if rc == 0 and not timed_out and not error:
                self.log.info(f"{self.log_as}_done", **fields)
                return
            self.log.warning(f"{self.log_as}_failed",
                             error=error or ("timeout" if timed_out else f"exit status {rc}"), **fields)
            if n < attempts:
                self._stopping.wait(self.cfg.retry_delay_s * n)
        self.log.error(f"{self.log_as}_gave_up", hook=index, **what, attempts=attempts)

    def _run_once(self, index: int, hook: HookConfig, notice, attempt: int):
        limit = self.cfg.output_limit
        where = f"hooks.{self.key}[{index}]"
        if not hook.argv:
            return None, False, f"{where}.argv is empty", "", ""
        env = dict(os.environ)
        env.update(notice.environment())
        env["POSED_HOOK_ATTEMPT"] = str(attempt)
        env[orphans.OWNER_ENV] = orphans.owner_tag(os.getppid(), os.getpid())
        with self._lock:
            if self._stopping.is_set():
                return None, False, "not started: the daemon is stopping", "", ""
            try:
                proc = start_program(hook.argv, env)
            except OSError as exc:
                return None, False, cannot_start(hook.argv, exc, where), "", ""
            self._proc = proc
        try:
            rc, timed_out, out, err = finish_program(proc, json.dumps(notice.to_json()).encode(), limit,
                                                     hook.timeout_s)
        finally:
            with self._lock:
                self._proc = None
        return (rc, timed_out, "", out[:limit].decode("utf-8", "replace"), err[:limit].decode("utf-8", "replace"))
