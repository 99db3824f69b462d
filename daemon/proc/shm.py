"""Shared-memory segments: the supervisor creates and unlinks them, stage processes only attach.

CPython 3.11 registers every ``SharedMemory`` it opens with the resource tracker, also one that merely
attaches, and spawned children share the supervisor's tracker. A child that registered a segment would make
the tracker unlink it (with a warning) when it thinks the segment leaked, and a child that unregistered it
would remove the supervisor's own registration. :func:`attach` therefore opens without registering at all;
only :func:`create` (the supervisor) registers, and :func:`destroy` unlinks and unregisters.

Segment names are ``posed-<pid of the supervisor>-<what>`` so that :func:`remove_stale` can delete the
segments of a supervisor that was killed (kill -9 leaves them in /dev/shm).
"""

from __future__ import annotations

import os
import re
from multiprocessing import resource_tracker, shared_memory
from pathlib import Path

PREFIX = "posed-"
_SHM_DIR = Path("/dev/shm")


def segment_name(what: str, pid: int | None = None) -> str:
    return f"{PREFIX}{os.getpid() if pid is None else pid}-{what}"


def create(what: str, size: int) -> shared_memory.SharedMemory:
    """Create (and zero) a segment owned by this process; unlink it with :func:`destroy`."""
    return shared_memory.SharedMemory(name=segment_name(what), create=True, size=max(1, size))


def attach(name: str) -> shared_memory.SharedMemory:
    """Open an existing segment without registering it with the resource tracker (stage processes)."""
    original = resource_tracker.register
    resource_tracker.register = _no_register
    try:
        return shared_memory.SharedMemory(name=name, create=False)
    finally:
        resource_tracker.register = original


def _no_register(name: str, rtype: str) -> None:
    return None


def destroy(segment: shared_memory.SharedMemory) -> None:
    """Close and unlink a segment this process created (idempotent)."""
    release(segment, owner=True)


def release(segment: shared_memory.SharedMemory, owner: bool) -> None:
    """Detach from a segment; its ``owner`` (the process that created it) also unlinks it (idempotent)."""
    try:
        segment.close()
    except (BufferError, OSError):
        pass
    if owner:
        try:
            segment.unlink()
        except FileNotFoundError:
            pass


def remove_stale(shm_dir: Path = _SHM_DIR) -> list[str]:
    """Unlink ``posed-<pid>-*`` segments whose supervisor process no longer exists; returns their names."""
    removed = []
    if not shm_dir.is_dir():
        return removed
    for path in shm_dir.glob(f"{PREFIX}*"):
        m = re.fullmatch(rf"{PREFIX}(\d+)-.+", path.name)
        if not m or _alive(int(m.group(1))):
            continue
        try:
            path.unlink()
            removed.append(path.name)
        except OSError:
            pass
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
