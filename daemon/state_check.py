"""Would the daemon's state directory take its files? Asked by ``posed config check`` (a problem: exit 78) and
by ``posed run`` (a warning: the daemon starts anyway and runs degraded, fall events kept in memory and in the
fallback file, daemon.outbox.fallback).

The folder is created if missing (as the daemon would), a probe file written, synced and removed; a folder on a
file system with less than ``MIN_FREE_BYTES`` free is called full.
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

MIN_FREE_BYTES = 1 << 20        # 1 MiB: a few hundred fall-event messages and some minutes of joint angles


def state_dir_problems(folder: Path) -> list[str]:
    """What keeps ``folder`` (``pipeline.state_dir`` resolved) from taking the daemon's files; [] when fine."""
    folder = Path(folder)
    fix = (f"give posed a writable folder with free space: pipeline.state_dir (now {folder}), or fix the disk "
           "(mount read-write, free space)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return [f"pipeline.state_dir: cannot create {folder}: {exc.strerror or exc}; {fix}"]
    if not folder.is_dir():
        return [f"pipeline.state_dir: {folder} is not a folder; {fix}"]
    probe = folder / f".posed-write-probe-{os.getpid()}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, b"posed")
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as exc:
        what = {errno.EROFS: "is on a read-only file system", errno.ENOSPC: "is on a full disk",
                errno.EACCES: "is not writable by this user", errno.EDQUOT: "is over its disk quota"}.get(
                    exc.errno, f"cannot be written ({exc.strerror or exc})")
        return [f"pipeline.state_dir: {folder} {what}; fall events would only be kept in memory and the "
                f"fallback file; {fix}"]
    finally:
        try:
            probe.unlink()
        except OSError:
            pass
    free = shutil.disk_usage(folder).free
    if free < MIN_FREE_BYTES:
        return [f"pipeline.state_dir: {folder} has only {free} bytes free (at least {MIN_FREE_BYTES} needed); "
                f"fall events would only be kept in memory and the fallback file; {fix}"]
    return []


class StateDirInUse(RuntimeError):
    """Another running posed daemon holds the state directory; the message names it and the fix."""


def claim_state_dir(folder: Path) -> int | None:
    """Hold ``folder`` (``pipeline.state_dir`` resolved) for this daemon while the process lives: an exclusive
    ``flock`` on the folder itself (no file is added; the kernel lets it go when the process exits, also on kill
    -9). Returns the descriptor to keep open, None when the folder cannot be opened or locked at all (missing,
    unreadable, a file system without locks: the daemon then runs degraded or unchecked, as before).

    Raises :class:`StateDirInUse` when another process holds it: two daemons on one state dir would write one
    event journal and one history (each taking the other's fall events back at its next start and answering
    them as its own), one learned geometry per camera and one fallback file."""
    import fcntl

    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _lock_holder(fd)
        os.close(fd)
        raise StateDirInUse(
            f"pipeline.state_dir: {folder} is in use by another posed daemon ({holder}); two daemons on one state "
            "directory would mix their fall-event journals and histories; give each daemon its own "
            "pipeline.state_dir (e.g. /var/lib/posed/<robot_id>), or stop the other one first") from None
    except OSError:
        os.close(fd)
        return None
    return fd


def _lock_holder(fd: int) -> str:
    """Who holds the flock on ``fd``'s file: "pid N: its command line" from /proc/locks, or "pid unknown"."""
    st = os.fstat(fd)
    where = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    try:
        with open("/proc/locks") as fh:
            pids = [int(f[4]) for f in (line.split() for line in fh)
                    if len(f) > 5 and f[1] == "FLOCK" and f[5] == where]
    except (OSError, ValueError):
        pids = []
    if not pids:
        return "pid unknown"
    try:
        with open(f"/proc/{pids[0]}/cmdline", "rb") as fh:
            cmd = fh.read(4096).replace(b"\0", b" ").decode("utf-8", "replace").strip()
    except OSError:
        cmd = ""
    cmd = cmd if len(cmd) <= 300 else cmd[:297] + "..."
    return f"pid {pids[0]}" + (f": {cmd}" if cmd else "")
