"""Processes a dead stage left behind: its hooks.

Hooks run in sessions of their own (so a timeout can end a hook and every child it started), which also means
that neither a kill -9 of the publisher nor one of the daemon's whole process group reaches them. Each hook
therefore carries ``POSED_HOOK_OWNER=<supervisor pid>:<stage pid>`` in its environment, and every child it
starts inherits it. The supervisor ends the processes of a stage it found dead before it starts the stage
again, everything its own stages left at shutdown, and at start-up whatever a killed supervisor's stages left
(an owner supervisor that no longer runs). Linux ``/proc`` only; elsewhere nothing is found.
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


def owned(match: Callable[[int, int], bool], proc: Path = Path("/proc")) -> list[int]:
    """Pids of the processes whose ``POSED_HOOK_OWNER`` (supervisor pid, stage pid) satisfies ``match``."""
    me = os.getpid()
    found = []
    try:
        entries = list(proc.iterdir())
    except OSError:
        return []
    for entry in entries:
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
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
