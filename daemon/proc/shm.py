"""Shared-memory segments: the supervisor creates and unlinks them, stage processes only attach.

CPython 3.11 registers every ``SharedMemory`` it opens with the resource tracker, also one that merely
attaches, and spawned children share the supervisor's tracker. A child that registered a segment would make
the tracker unlink it (with a warning) when it thinks the segment leaked, and a child that unregistered it
would remove the supervisor's own registration. :func:`attach` therefore opens without registering at all;
only :func:`create` (the supervisor) registers, and :func:`destroy` unlinks and unregisters.

Segment names are ``posed-<pid of the supervisor>-<what>`` so that :func:`remove_stale` can delete the
segments of a supervisor that was killed (kill -9 leaves them in /dev/shm). The doorbell semaphores are
multiprocessing's (``/dev/shm/sem.mp-<random>``, unlinked by the resource tracker, which a kill -9 of the
whole group also kills): the supervisor lists their names in ``posed-<pid>-semaphores``
(:func:`record_semaphores`), and :func:`remove_stale` unlinks the listed ones of a supervisor that is gone,
and no other ``sem.*`` file.
"""

from __future__ import annotations

import os
import re
from multiprocessing import resource_tracker, shared_memory
from pathlib import Path

PREFIX = "posed-"
_SHM_DIR = Path("/dev/shm")
SEMAPHORES = "semaphores"
_SEM_NAME = re.compile(r"/?(mp-[A-Za-z0-9_]+)")


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


def record_semaphores(names: list[str], shm_dir: Path = _SHM_DIR) -> Path | None:
    """Write the names of this process's named semaphores (``/mp-xxxx``) to ``posed-<pid>-semaphores`` so
    that the next start can remove them if this process is killed; None when /dev/shm is not there."""
    if not shm_dir.is_dir():
        return None
    path = shm_dir / segment_name(SEMAPHORES)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        fh.write("".join(f"{n}\n" for n in names))
    return path


def remove_stale(shm_dir: Path = _SHM_DIR) -> list[str]:
    """Unlink ``posed-<pid>-*`` segments whose supervisor process no longer exists, and the semaphores such
    a supervisor listed; returns the names removed."""
    removed = []
    if not shm_dir.is_dir():
        return removed
    for path in shm_dir.glob(f"{PREFIX}*"):
        m = re.fullmatch(rf"{PREFIX}(\d+)-(.+)", path.name)
        if not m or _alive(int(m.group(1))):
            continue
        if m.group(2) == SEMAPHORES:
            removed += _remove_semaphores(path, shm_dir)
        try:
            path.unlink()
            removed.append(path.name)
        except OSError:
            pass
    return removed


def _remove_semaphores(record: Path, shm_dir: Path) -> list[str]:
    try:
        text = record.read_text()[:65536]
    except OSError:
        return []
    removed = []
    for line in text.splitlines():
        m = _SEM_NAME.fullmatch(line.strip())
        if not m:
            continue
        sem = shm_dir / f"sem.{m.group(1)}"
        try:
            sem.unlink()
            removed.append(sem.name)
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
