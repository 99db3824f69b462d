"""Processes a dead stage left behind: its hooks.

Hooks run in sessions of their own (so a timeout can end a hook and every child it started), which also means
that neither a kill -9 of the publisher nor one of the daemon's whole process group reaches them. Each hook
therefore carries ``POSED_HOOK_OWNER=<supervisor pid>:<stage pid>`` in its environment, and every child it
starts inherits it. The supervisor ends the processes of a stage it found dead before it starts the stage
again, everything its own stages left at shutdown, and at start-up whatever a killed supervisor's stages left
(an owner supervisor that no longer runs). Linux ``/proc`` only; elsewhere nothing is found.

A hook may also leave its session (``setsid``) and clear its environment (``env -i``): no tag, no group. So
the publisher is a child subreaper (:func:`become_subreaper`, Linux ``PR_SET_CHILD_SUBREAPER``): whatever a
hook leaves behind when it exits is re-parented to the publisher instead of init. The publisher reaps those
adopted processes when they exit (:func:`reap_adopted`) and ends every descendant when it stops
(:func:`descendants`), which it also does when the supervisor was killed -9 (the stages notice their parent is
gone and stop).
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable
from pathlib import Path

OWNER_ENV = "POSED_HOOK_OWNER"
_KEY = OWNER_ENV.encode() + b"="
TERM_GRACE_S = 0.5


def owner_tag(supervisor_pid: int, stage_pid: int) -> str:
    """The value of ``POSED_HOOK_OWNER`` for a hook started by ``stage_pid`` under ``supervisor_pid``."""
    return f"{supervisor_pid}:{stage_pid}"


def _pid_namespace(path: Path) -> str | None:
    try:
        return os.readlink(path / "ns" / "pid")
    except OSError:
        return None


def owned(match: Callable[[int, int], bool], proc: Path = Path("/proc")) -> list[int]:
    """Pids of the processes whose ``POSED_HOOK_OWNER`` (supervisor pid, stage pid) satisfies ``match``.

    Only processes of this process's pid namespace count: the pids in the tag of a hook started in another one
    (a daemon in a container, whose processes the host sees) are that namespace's, and a supervisor alive there
    may look dead here; its hooks are not this daemon's to end."""
    me = os.getpid()
    own_ns = _pid_namespace(proc / "self")
    found = []
    try:
        entries = list(proc.iterdir())
    except OSError:
        return []
    for entry in entries:
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        if own_ns is not None and _pid_namespace(entry) != own_ns:
            continue        # another pid namespace's (or gone, or not ours to read)
        try:
            env = (entry / "environ").read_bytes()
        except OSError:     # gone, or not ours to read
            continue
        for item in env.split(b"\0"):
            if item.startswith(_KEY):
                try:
                    sup, stage = (int(v) for v in item[len(_KEY):].split(b":"))
                except ValueError:
                    break
                if match(sup, stage):
                    found.append(int(entry.name))
                break
    return found


def alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def end(pids: list[int], grace_s: float = TERM_GRACE_S) -> int:
    """SIGTERM to each, SIGKILL to those still running after ``grace_s``; returns how many were signalled."""
    sent = 0
    for pid in pids:
        try:
            os.kill(pid, signal.SIGTERM)
            sent += 1
        except (ProcessLookupError, PermissionError):
            pass
    deadline = time.monotonic() + grace_s
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.02)
    for pid in pids:
        if alive(pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
    return sent


def of_stage(supervisor_pid: int, stage_pid: int) -> list[int]:
    """What one (dead) stage of this supervisor left running."""
    return owned(lambda sup, stage: sup == supervisor_pid and stage == stage_pid)


def of_supervisor(supervisor_pid: int) -> list[int]:
    """What any stage of this supervisor left running."""
    return owned(lambda sup, _stage: sup == supervisor_pid)


def of_dead_supervisors() -> list[int]:
    """What the stages of supervisors that no longer run left behind (a kill -9 of the whole daemon)."""
    return owned(lambda sup, _stage: not alive(sup))


PR_SET_CHILD_SUBREAPER = 36


def become_subreaper() -> bool:
    """Make this process the one orphaned descendants are re-parented to (Linux 3.4+); False elsewhere."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _stat(pid: str, proc: Path) -> tuple[int, str] | None:
    """(parent pid, state letter) of a process, None when it is gone."""
    try:
        rest = (proc / pid / "stat").read_text().rsplit(")", 1)[1].split()
        return int(rest[1]), rest[0]
    except (OSError, IndexError, ValueError):
        return None


def descendants(root: int, proc: Path = Path("/proc")) -> list[int]:
    """Every process below ``root`` (children, their children, ...), found through /proc's parent pids."""
    children: dict[int, list[int]] = {}
    try:
        entries = [e.name for e in proc.iterdir() if e.name.isdigit()]
    except OSError:
        return []
    for name in entries:
        st = _stat(name, proc)
        if st is not None:
            children.setdefault(st[0], []).append(int(name))
    out, todo = [], list(children.get(root, []))
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo += children.get(pid, [])
    return out


def reap_adopted(keep: set[int], proc: Path = Path("/proc")) -> int:
    """Reap this process's exited children other than ``keep`` (the hooks it started itself, which their
    ``subprocess.Popen`` waits for): what a subreaper adopted. Returns how many were reaped."""
    me, reaped = os.getpid(), 0
    for pid in descendants(me, proc):
        st = _stat(str(pid), proc)
        if st is None or st[0] != me or st[1] != "Z" or pid in keep:
            continue
        try:
            if os.waitpid(pid, os.WNOHANG)[0] == pid:
                reaped += 1
        except ChildProcessError:
            pass
    return reaped

