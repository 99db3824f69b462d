"""Several real ``posed run`` daemons at once (each its own robot id, state dir, Zenoh port, process group),
replaying a real fall recording (URFD landmarks), and what they logged and journalled."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FALL = Path("falls") / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"


def log_events(out: Path, name: str) -> list[dict]:
    """The JSON log lines in the file ``out`` (a daemon's stdout with ``logging.format=json``) whose event is
    ``name``."""
    found = []
    for line in out.read_text(errors="replace").splitlines():
        if line.startswith("{") and f'"{name}"' in line:
            try:
                obj = json.loads(line)
            except ValueError:
                continue
            if obj.get("event") == name:
                found.append(obj)
    return found


class Daemon:
    """One ``posed run`` in a session of its own (so a kill -9 of its whole group reaches only it); ``prefix``:
    what runs it (e.g. ``unshare --pid --fork``: a pid namespace of its own, as in a container); ``env``: added to
    its environment."""

    def __init__(self, tmp_path: Path, name: str, robot: str, port: int, shared_data: Path, *,
                 state: Path | None = None, connect: int | None = None, extra: tuple[str, ...] = (),
                 prefix: tuple[str, ...] = (), env: dict[str, str] | None = None) -> None:
        self.dir = tmp_path / name
        self.dir.mkdir(parents=True, exist_ok=True)
        self.robot, self.port = robot, port
        self.state = state or self.dir / "state"
        self.endpoint = f"tcp/127.0.0.1:{port}"
        cmd = [*prefix, sys.executable, "-m", "posed.cli", "run", "--source", f"file:{shared_data / FALL}?loop=true",
               "--set", f"robot_id={robot}", "--set", f"pipeline.state_dir={self.state}",
               "--set", f"zenoh.listen=[{self.endpoint}]", "--set", "logging.format=json",
               "--set", "pipeline.status_period_s=0.5", *extra]
        if connect is not None:
            cmd += ["--set", f"zenoh.connect=[tcp/127.0.0.1:{connect}]"]
        self.out, self.err = self.dir / "out.log", self.dir / "err.log"
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env={**os.environ, **(env or {})}, stdout=open(self.out, "w"),
                                     stderr=open(self.err, "w"), start_new_session=True)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def events(self, name: str) -> list[dict]:
        """The log lines (JSON) whose event is ``name``."""
        return log_events(self.out, name)

    def journal(self) -> list[tuple]:
        """(robot, event id, state, acked_at) of every message in the daemon's journal."""
        path = self.state / "events.sqlite3"
        if not path.exists():
            return []
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as db:
            return list(db.execute("SELECT robot, event_id, state, acked_at FROM messages"))

    def wait_log(self, name: str, timeout: float) -> list[dict]:
        return wait(lambda: self.events(name), timeout, f"{self.robot}'s {name} log line", self)

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 20.0) -> int:
        if self.proc.poll() is None:
            os.kill(self.proc.pid, sig)
        return self.proc.wait(timeout)

    def kill_group(self) -> None:
        """kill -9 of the daemon's whole process group (supervisor, stages, resource tracker)."""
        os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(10)


def wait(pred, timeout: float, what: str, daemon: Daemon | None = None):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        if daemon is not None and daemon.proc.poll() is not None:
            raise AssertionError(f"{daemon.robot}'s daemon exited ({daemon.proc.returncode}) while waiting for "
                                 f"{what}: {daemon.err.read_text()[-2000:]}")
        time.sleep(0.1)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def stop_all(*daemons: Daemon) -> None:
    """SIGTERM (the daemon unlinks its shared memory), kill -9 of the group for one that does not stop."""
    for d in daemons:
        try:
            d.stop(timeout=15)
        except subprocess.TimeoutExpired:
            d.kill_group()
