"""Two real ``posed run`` daemons in pid namespaces of their own sharing one /dev/shm (two containers started with
``--ipc=host`` or a bind-mounted /dev/shm), as ``unshare --pid --fork`` makes them: both supervisors are pid 1,
so their shared-memory names (``posed-<pid>-*``) meet.

Fails without the fix: the second daemon stopped with exit status 70 (FileExistsError on ``posed-1-control``),
after overwriting the first one's semaphore list and unlinking it on its way out. Now the second one runs beside
the first (its names get a suffix), and a third started after a kill -9 of the first replaces what the first left
(nobody holds it any more) while the second one's files, held by it, stay.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from pathlib import Path

import pytest

from tests.daemon.robots_util import Daemon, stop_all, wait
from tests.daemon.zenoh_util import free_port

SHM = Path("/dev/shm")
UNSHARE = ("unshare", "--pid", "--fork")


def _stop(*daemons: Daemon) -> None:
    """SIGTERM to each namespace's pid 1 (the supervisor: it unlinks its shared memory), then the rest."""
    for d in daemons:
        try:
            children = Path(f"/proc/{d.pid}/task/{d.pid}/children").read_text().split()
        except OSError:
            children = []
        for child in children:
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(child), signal.SIGTERM)
    for d in daemons:
        with contextlib.suppress(subprocess.TimeoutExpired):
            d.proc.wait(20)
    stop_all(*daemons)


def _pid1_files() -> set[str]:
    return {p.name for p in SHM.glob("posed-1-*")}


@pytest.fixture(scope="module")
def pid_namespaces():
    try:
        ok = subprocess.run([*UNSHARE, "true"], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        ok = False
    if not ok:
        pytest.skip("cannot make a pid namespace here (unshare --pid needs CAP_SYS_ADMIN)")
    if _pid1_files():
        pytest.skip(f"/dev/shm already holds another pid 1's posed files: {sorted(_pid1_files())}")


def test_daemons_in_two_pid_namespaces_share_dev_shm(tmp_path, shared_data, pid_namespaces):
    a = Daemon(tmp_path, "a", "nsA", free_port(), shared_data, prefix=UNSHARE)
    b = c = None
    try:
        a.wait_log("zenoh_open", 90)
        a_files = _pid1_files()
        a_record = SHM / "posed-1-semaphores"
        assert {"posed-1-control", a_record.name} <= a_files
        a_semaphores = a_record.read_text()

        b = Daemon(tmp_path, "b", "nsB", free_port(), shared_data, prefix=UNSHARE)
        b.wait_log("zenoh_open", 90)
        assert b.proc.poll() is None, b.out.read_text()[-3000:]
        b_files = _pid1_files() - a_files
        assert any(n.startswith("posed-1-control-") for n in b_files), b_files
        assert a_files <= _pid1_files() and a_record.read_text() == a_semaphores
        assert not b.events("removed_stale_shared_memory")

        a.kill_group()                                   # the first container killed: its files stay behind
        listed = [SHM / f"sem.{n.strip().lstrip('/')}" for n in a_semaphores.splitlines() if n.strip()]
        assert listed and all(p.exists() for p in listed)
        c = Daemon(tmp_path, "c", "nsC", free_port(), shared_data, prefix=UNSHARE)
        c.wait_log("zenoh_open", 90)
        assert c.proc.poll() is None and b.proc.poll() is None
        assert b_files <= _pid1_files(), "the running daemon's shared memory was removed"
        assert not any(p.exists() for p in listed), "the killed daemon's semaphores were left"
        assert a_record.read_text() != a_semaphores            # the name is the new daemon's now
    finally:
        _stop(*(d for d in (a, b, c) if d is not None))
    wait(lambda: not _pid1_files(), 20, "the stopped daemons to unlink their shared memory")


def test_a_start_leaves_the_hooks_of_another_pid_namespace_alone(tmp_path, shared_data, pid_namespaces):
    """A daemon's start ends the hooks a killed supervisor left (POSED_HOOK_OWNER names a supervisor that no
    longer runs). A hook of a daemon in a container carries that container's pids, and its supervisor, alive
    there, looks dead from the host. Fails without the fix: the host daemon's start ended it."""
    gone = subprocess.Popen(["true"])
    gone.wait()
    hook = subprocess.Popen([*UNSHARE, "env", f"POSED_HOOK_OWNER={gone.pid}:{gone.pid}", "sleep", "120"],
                            start_new_session=True)
    d = None
    try:
        inner = wait(lambda: Path(f"/proc/{hook.pid}/task/{hook.pid}/children").read_text().split(), 10,
                     "the hook in its pid namespace")
        sleeper = int(inner[0])
        wait(lambda: b"POSED_HOOK_OWNER" in Path(f"/proc/{sleeper}/environ").read_bytes(), 10, "its tag")
        d = Daemon(tmp_path, "host", "hostRobot", free_port(), shared_data)
        d.wait_log("zenoh_open", 90)
        ended = [p for e in d.events("hooks_left_behind_ended") for p in e.get("pids", [])]
        assert sleeper not in ended, ended
        state = Path(f"/proc/{sleeper}/stat").read_text().rsplit(")", 1)[1].split()[0]
        assert state != "Z", "the other namespace's hook was ended"
    finally:
        if d is not None:
            stop_all(d)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(hook.pid, signal.SIGKILL)
        hook.wait(10)
