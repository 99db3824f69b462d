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

Names are per pid, and a pid says nothing across pid namespaces: daemons in two containers that share /dev/shm
(``--ipc=host``, a bind-mounted /dev/shm) both run as pid 1 or 7, and a pid that looks dead here may run there.
So the supervisor also holds a shared ``flock`` on each file it made (segments and the semaphore list; the
kernel lets it go when the process ends, also with SIGKILL): :func:`remove_stale` leaves a file that is held,
whatever its pid says; :func:`create` and :func:`record_semaphores` replace a file of their own name that nobody
holds (a leftover: a restarted container's pid 1 is alive, so its old files look in use) and give a name held by
a live daemon a suffix (``posed-1-control-3f2a9c``) rather than fail on it or overwrite it.

A segment's pages are reserved when it is created (:func:`reserve`: ``posix_fallocate`` on its fd). Without
that, a full /dev/shm (a container's 64 MB default, another program's files) is found only when a page is
first written: the writing process (the supervisor, or the capture stage in a restart loop) dies of SIGBUS
with no message. Reserved, a full /dev/shm is :class:`SharedMemoryFull` at creation, which says how much was
needed and free and the fix, and the supervisor stops with exit status 78.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import secrets
from multiprocessing import resource_tracker, shared_memory
from pathlib import Path

PREFIX = "posed-"
_SHM_DIR = Path("/dev/shm")
SEMAPHORES = "semaphores"
_SEM_NAME = re.compile(r"/?(mp-[A-Za-z0-9_]+)")


def segment_name(what: str, pid: int | None = None) -> str:
    return f"{PREFIX}{os.getpid() if pid is None else pid}-{what}"


class SharedMemoryFull(OSError):
    """/dev/shm has not room for a segment (or a doorbell semaphore); ``fix`` says what to do."""

    def __init__(self, message: str, fix: str, needed: int, free: int | None) -> None:
        super().__init__(errno.ENOSPC, message)
        self.message, self.fix, self.needed, self.free = message, fix, needed, free

    def __str__(self) -> str:
        return self.message


FULL_FIX = ("free space in /dev/shm (see `df -h /dev/shm`; posed's own segments left by a killed daemon are "
            "removed at start), or make /dev/shm larger: in a container start it with a larger --shm-size "
            "(Docker's default is 64 MB; Kubernetes: a memory-backed emptyDir mounted on /dev/shm), on a host "
            "`mount -o remount,size=1G /dev/shm` (lasting: a size= option for /dev/shm in /etc/fstab); or make "
            "the frame ring smaller (pipeline.ring_slots, pipeline.frame_max_pixels)")


def free_bytes(shm_dir: Path = _SHM_DIR) -> int | None:
    """Bytes an unprivileged process may still use in ``shm_dir`` (None when it cannot be asked)."""
    try:
        st = os.statvfs(shm_dir)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


def full_error(what: str, needed: int, shm_dir: Path = _SHM_DIR, out_of_memory: bool = False) -> SharedMemoryFull:
    """The error for a ``what`` (e.g. "the ring segment posed-12-ring") of ``needed`` bytes that did not fit
    (``out_of_memory``: the kernel said ENOMEM, i.e. the memory limit of the cgroup rather than the tmpfs's size)."""
    free = free_bytes(shm_dir)
    free_text = "unknown" if free is None else _mb(free)
    message = (f"{shm_dir} has no room for {what}: it needs {_mb(needed)} ({needed} bytes) of shared memory and "
               f"{shm_dir} has {free_text} free")
    fix = FULL_FIX
    if out_of_memory:
        message += " (the kernel refused the memory: the memory limit of this service or container is reached)"
        fix = "raise the memory limit (systemd MemoryMax=, docker --memory) or " + FULL_FIX
    return SharedMemoryFull(message, fix, needed, free)


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 1_000_000 else f"{n / 1e3:.0f} kB"


@contextlib.contextmanager
def no_room_is_full(what: str, needed: int):
    """Within it, an ENOSPC from creating ``what`` (``needed`` bytes) in /dev/shm is :class:`SharedMemoryFull`."""
    try:
        yield
    except SharedMemoryFull:
        raise
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise full_error(what, needed) from exc
        raise


def reserve(fd: int, size: int, what: str, shm_dir: Path = _SHM_DIR) -> None:
    """Allocate every page of the ``size`` bytes of the file ``fd`` (a segment in ``shm_dir``, a tmpfs) now, so
    that writing into it later can never fail for want of space (a tmpfs page allocated at the first write
    that finds the file system full raises SIGBUS); :class:`SharedMemoryFull` when there is not room."""
    if size <= 0:
        return
    try:
        os.posix_fallocate(fd, 0, size)
    except OSError as exc:
        if exc.errno in (errno.ENOSPC, errno.ENOMEM, errno.EDQUOT):
            raise full_error(what, size, shm_dir, out_of_memory=exc.errno == errno.ENOMEM) from exc
        raise


def create(what: str, size: int) -> shared_memory.SharedMemory:
    """Create (and zero) a segment owned by this process with all its pages reserved (:func:`reserve`), held
    (a shared flock) while this process keeps it; unlink it with :func:`destroy`. :class:`SharedMemoryFull` (and
    nothing left behind) when /dev/shm has not room for it. A name another live daemon holds (another pid
    namespace) gets a suffix; a name nobody holds is a leftover and is replaced."""
    name = segment_name(what)
    size = max(1, size)
    for _ in range(3):
        try:
            with no_room_is_full(f"the {what} segment {name}", size):
                segment = shared_memory.SharedMemory(name=name, create=True, size=size)
            break
        except FileExistsError:
            name = _free_name(name, segment_name(what))
    else:
        segment = shared_memory.SharedMemory(name=name, create=True, size=size)    # says which name exists
    try:
        fcntl.flock(segment._fd, fcntl.LOCK_SH)
        reserve(segment._fd, size, f"the {what} segment {name}")
    except BaseException:
        destroy(segment)
        raise
    return segment


def _held(path: Path) -> bool:
    """True when a running process holds a flock on ``path`` (a supervisor of any pid namespace)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return False
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def _free_name(name: str, base: str, shm_dir: Path = _SHM_DIR) -> str:
    """After ``name`` was found to exist: the same name once a leftover nobody holds is removed, or ``base``
    with a random suffix when a live daemon (another pid namespace) holds it."""
    path = shm_dir / name
    if _held(path):
        return f"{base}-{secrets.token_hex(3)}"
    if base.endswith(f"-{SEMAPHORES}"):
        _remove_semaphores(path, shm_dir)       # a killed supervisor's list: its semaphores go with it
    with contextlib.suppress(OSError):
        path.unlink()
    return name


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


_HELD_RECORDS: dict[Path, int] = {}       # the semaphore lists this process wrote, held (flock) while it lives


def record_semaphores(names: list[str], shm_dir: Path = _SHM_DIR) -> Path | None:
    """Write the names of this process's named semaphores (``/mp-xxxx``) to ``posed-<pid>-semaphores`` (held
    while this process lives) so that the next start can remove them if this process is killed; None when
    /dev/shm is not there. A list of the same name that a live daemon holds (another pid namespace) is left
    alone: this one gets a suffix."""
    if not shm_dir.is_dir():
        return None
    base = segment_name(SEMAPHORES)
    path = shm_dir / base
    for _ in range(3):
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
            break
        except FileExistsError:
            path = shm_dir / _free_name(path.name, base, shm_dir)
    else:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
    fcntl.flock(fd, fcntl.LOCK_SH)
    os.write(fd, "".join(f"{n}\n" for n in names).encode())
    _HELD_RECORDS[path] = fd
    return path


def remove_stale(shm_dir: Path = _SHM_DIR) -> list[str]:
    """Unlink ``posed-<pid>-*`` segments whose supervisor process no longer exists and that no running
    supervisor holds (one in another pid namespace), and the semaphores such a supervisor listed; returns the
    names removed."""
    removed = []
    if not shm_dir.is_dir():
        return removed
    for path in shm_dir.glob(f"{PREFIX}*"):
        m = re.fullmatch(rf"{PREFIX}(\d+)-(.+)", path.name)
        if not m:
            continue
        if _alive(int(m.group(1))) or _held(path):
            continue
        if m.group(2) == SEMAPHORES or m.group(2).startswith(f"{SEMAPHORES}-"):
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
