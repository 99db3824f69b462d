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
