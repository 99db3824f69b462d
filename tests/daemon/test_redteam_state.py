"""What the daemon leaves on the machine and says about itself, with the real supervisor and stages: the
semaphores a kill -9 of the whole group leaves in /dev/shm are removed at the next start (only those, never
another process's), the state folder is 0700 and the journal and history files 0600, and a missing camera
reads ``waiting_for_camera`` in the status and in systemd's STATUS= line."""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

from tests.daemon.harness import NotifyListener
from tests.daemon.redteam_util import FileHarness, publisher_daemon, until
from tests.daemon.zenoh_util import client, free_port

ROOT = Path(__file__).resolve().parents[2]
SHM = Path("/dev/shm")


def _mapped_semaphores(pid: int) -> set[Path]:
    """The /dev/shm/sem.* files a process has mapped (its named semaphores), found by inode: glibc maps the
    file under a temporary name before linking it to the semaphore's."""
    inodes = set()
    for line in Path(f"/proc/{pid}/maps").read_text().splitlines():
        parts = line.split()
        if len(parts) >= 6 and parts[5].startswith("/dev/shm/sem."):
            inodes.add(int(parts[4]))
    return {p for p in SHM.glob("sem.*") if p.stat().st_ino in inodes}


def test_semaphores_left_by_a_kill_9_of_the_group_are_removed_at_next_start(tmp_path):
    foreign = multiprocessing.get_context("spawn").Semaphore(0)     # a live process's own semaphore
    foreign_file = SHM / f"sem.{foreign._semlock.name.lstrip('/')}"
    assert foreign_file.exists()
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = FileHarness(tmp_path / "a", publisher=False)
    try:
        first.wait_for(lambda s: s["ready"], 60, "the first supervisor to be ready")
        left = _mapped_semaphores(first.proc.pid)
        assert len(left) >= 3, left                                   # the doorbells
    finally:
        os.killpg(first.proc.pid, signal.SIGKILL)                     # supervisor, stages, resource tracker
        first.proc.wait()
    until(lambda: all(p.exists() for p in left), 2, "the semaphores to be left behind")
    second = FileHarness(tmp_path / "b", publisher=False)
    try:
        second.wait_for(lambda s: s["ready"], 60, "the second supervisor to be ready")
        assert not [p for p in left if p.exists()], "the dead supervisor's semaphores are still there"
        assert foreign_file.exists(), "a semaphore of a live process was removed"
        # (another posed starting on this machine meanwhile may be the one that removed them: both are right)
    finally:
        code, _, err, _ = second.stop()
    assert code == 0, err
    foreign_file_after = foreign_file.exists()
    del foreign
    assert foreign_file_after


def test_remove_stale_unlinks_only_the_semaphores_a_dead_supervisor_listed(tmp_path):
    from posed.daemon.proc import shm

    dead = _dead_pid()
    listed = ["mp-aaaa1111", "mp-bbbb2222"]
    for name in [*listed, "mp-cccc3333", "other"]:
        (tmp_path / f"sem.{name}").write_bytes(b"")
    (tmp_path / f"posed-{dead}-semaphores").write_text("/mp-aaaa1111\nmp-bbbb2222\n../../etc/passwd\n/x y\n")
    (tmp_path / f"posed-{os.getpid()}-semaphores").write_text("/mp-cccc3333\n")     # alive: untouched
    removed = shm.remove_stale(tmp_path)
    assert sorted(removed) == sorted([f"sem.{n}" for n in listed] + [f"posed-{dead}-semaphores"])
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["sem.mp-cccc3333", "sem.other", f"posed-{os.getpid()}-semaphores"])


def _dead_pid() -> int:
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def test_state_folder_0700_and_journal_and_history_0600(tmp_path):
    os.umask(0o022)
    h, ep = publisher_daemon(tmp_path)
    state = tmp_path / "state"
    try:
        with client(ep) as s:
            statuses = []
            _sub = s.declare_subscriber("posed/r7/status", lambda smp: statuses.append(
                json.loads(smp.payload.to_string())))
            until(lambda: statuses and statuses[-1]["events"]["unacknowledged"] >= 3, 30, "fall messages")
            until(lambda: (state / "history.sqlite3").exists(), 30, "the history file")
    finally:
        code, _, err, _ = h.stop()
    assert code == 0, err
    assert stat.S_IMODE(state.stat().st_mode) == 0o700
    files = [p for p in state.iterdir() if p.name.startswith(("events.sqlite3", "history.sqlite3"))]
    assert {"events.sqlite3", "history.sqlite3"} <= {p.name for p in files}
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == 0o600, (p.name, oct(p.stat().st_mode))


def test_missing_camera_is_waiting_for_camera_in_status_and_systemd(tmp_path):
    sock = str(tmp_path / "notify.sock")
    listener = NotifyListener(sock)
    ep = f"tcp/127.0.0.1:{free_port()}"
    with open(tmp_path / "out.log", "w") as out:
        proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "run", "--source", "v4l2:/dev/video99",
                                 "--set", f"pipeline.state_dir={tmp_path / 'state'}", "--set", "logging.format=json",
                                 "--set", f"zenoh.listen=[{ep}]", "--set", "robot_id=cam",
                                 "--set", "pipeline.status_period_s=0.3"],
                                cwd=ROOT, stdout=out, stderr=subprocess.STDOUT,
                                env={**os.environ, "NOTIFY_SOCKET": sock})
    statuses: list[dict] = []
    try:
        with client(ep) as s:
            _sub = s.declare_subscriber("posed/cam/status", lambda smp: statuses.append(
                json.loads(smp.payload.to_string())))
            until(lambda: any(x.get("ready") for x in statuses), 120, "the daemon to be ready")
            until(lambda: statuses[-1]["state"] == "waiting_for_camera", 10, "waiting_for_camera")
            st = statuses[-1]
            assert st["camera"]["state"] == "lost" and "/dev/video99" in st["camera"]["source"]
            texts = [m for _, m in listener.messages if m.startswith("STATUS=")]
            assert any("waiting_for_camera" in t and "/dev/video99" in t for t in texts), texts[-3:]
            assert not any(t.startswith("STATUS=running") for t in texts[-3:]), texts[-3:]
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(30)
        listener.close()
    assert proc.returncode == 0
