"""The state folder and its files are private to the daemon's user: fall events and joint-angle history
are health data.

:func:`private_folder` creates the state folder with mode 0700 (its parents with the default mode) and
tightens an existing one that holds nothing but the daemon's files; a folder shared with other files is
left alone with one warning. :func:`private_file` creates a file with mode 0600 before SQLite opens it
(SQLite gives its ``-wal`` and ``-shm`` files the main file's mode) and tightens an existing one. Only
files and folders this user owns are changed. systemd's ``StateDirectory=`` comes out the same way.
:func:`write_private` replaces a small file of the daemon's (learned geometry, a pause, events kept aside)
atomically, with mode 0600.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

FOLDER_MODE = 0o700
FILE_MODE = 0o600
OWN_PREFIXES = ("events.sqlite3", "history.sqlite3",     # with -wal, -shm and *.corrupt-* siblings
                "falls-geometry",                          # the fall detector's learned geometry per camera
                "privacy.json")                            # a pause for privacy (daemon.stages.privacy_file)


def private_folder(folder: Path, log=None) -> None:
    """Create ``folder`` (0700) or make an existing one of ours 0700 when it holds only the daemon's files."""
    folder = Path(folder)
    try:
        if not folder.exists():
            folder.parent.mkdir(parents=True, exist_ok=True)
            folder.mkdir(mode=FOLDER_MODE)
    except FileExistsError:
        pass
    except OSError as exc:      # read-only or full file system: the journal and the history say so and go on
        if log is not None:
            log.error("state_folder_unavailable", folder=str(folder), error=str(exc),
                      fix="make pipeline.state_dir writable (or point it at a writable disk); fall events are "
                          "kept in memory and in the fallback file meanwhile")
        return
    try:
        st = folder.stat()
        if st.st_uid != os.geteuid() or stat.S_IMODE(st.st_mode) == FOLDER_MODE:
            return
        if all(p.name.startswith(OWN_PREFIXES) for p in folder.iterdir()):
            folder.chmod(FOLDER_MODE)
        elif stat.S_IMODE(st.st_mode) & 0o077 and log is not None:
            log.warning("state_folder_not_private", folder=str(folder), mode=oct(stat.S_IMODE(st.st_mode)),
                        fix=f"the folder holds other files too; give posed a folder of its own "
                            f"(pipeline.state_dir) or chmod 700 {folder}")
    except OSError:
        pass


def private_file(path: Path) -> None:
    """Create ``path`` empty with mode 0600 if it is missing; make an existing file of ours (and its SQLite
    ``-wal``/``-shm`` siblings) 0600."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT, FILE_MODE)
        os.close(fd)
    except OSError:
        return                  # the caller's open reports what is wrong with the folder or the disk
    for p in (path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")):
        try:
            st = p.stat()
            if st.st_uid == os.geteuid() and stat.S_IMODE(st.st_mode) != FILE_MODE:
                p.chmod(FILE_MODE)
        except OSError:
            pass


def write_private(path: Path, text: str) -> None:
    """Replace ``path``'s content with ``text`` atomically (a temporary sibling, fsync'd, renamed over it), mode
    0600; raises OSError (a read-only, full or missing folder) and then leaves no temporary file behind (a full
    disk would leave an empty one)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, FILE_MODE)
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise
