"""A real ``posed run`` for the pause-for-privacy tests: a recording replayed in a loop at its own pace (so it
runs until stopped), on its own Zenoh port and state dir, in a session of its own, with what a viewer on the bus
received (poses and statuses, with their arrival times) and a watch hook that writes each run to a file."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from tests.daemon.robots_util import log_events
from tests.daemon.zenoh_util import client

ROOT = Path(__file__).resolve().parents[2]
SQUAT = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"
FALL = Path("falls") / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"

# one line per run of the watch hook: watch|reason|stdin
WATCH_HOOK = 'echo "$POSED_WATCH|$POSED_WATCH_REASON|$(cat)" >> "$1"\n'


class PosedRun:
    """``posed run --source file:SOURCE`` with ``overrides``; ``notify``: a NOTIFY_SOCKET path (systemd's side)."""

    def __init__(self, tmp_path: Path, name: str, source: str, robot: str, port: int, *overrides: str,
                 state: Path | None = None, notify: str | None = None) -> None:
        self.dir = tmp_path / name
        self.dir.mkdir(parents=True, exist_ok=True)
        self.robot, self.endpoint = robot, f"tcp/127.0.0.1:{port}"
        self.state = state or tmp_path / "state"
        cmd = [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{source}",
               "--set", f"robot_id={robot}", "--set", f"pipeline.state_dir={self.state}",
               "--set", f"zenoh.listen=[{self.endpoint}]", "--set", "logging.format=json",
               "--set", "pipeline.status_period_s=0.5"]
        for o in overrides:
            cmd += ["--set", o]
        env = {**os.environ, **({"NOTIFY_SOCKET": notify} if notify else {})}
        self.out = self.dir / "out.log"
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=open(self.out, "w"),
                                     stderr=open(self.dir / "err.log", "w"), start_new_session=True)

    def events(self, name: str) -> list[dict]:
        return log_events(self.out, name)

    def stop(self, timeout: float = 20.0) -> int:
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGTERM)
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            return self.proc.wait(10)


class Viewer:
    """A client session on the daemon's endpoint: every pose and status with its arrival (monotonic) time."""

    def __init__(self, endpoint: str, robot: str) -> None:
        self.session = client(endpoint)
        self.lock = threading.Lock()
        self.poses: list[tuple[float, dict]] = []
        self.statuses: list[tuple[float, dict]] = []
        self._keep = [self.session.declare_subscriber(f"posed/{robot}/pose", self._on(self.poses)),
                      self.session.declare_subscriber(f"posed/{robot}/status", self._on(self.statuses))]

    def _on(self, into: list):
        def keep(sample) -> None:
            with self.lock:
                into.append((time.monotonic(), json.loads(sample.payload.to_string())))
        return keep

    def poses_between(self, t0: float, t1: float = float("inf")) -> int:
        with self.lock:
            return sum(1 for t, _ in self.poses if t0 <= t <= t1)

    def statuses_since(self, t0: float) -> list[dict]:
        with self.lock:
            return [s for t, s in self.statuses if t >= t0]

    def last_status(self) -> dict | None:
        with self.lock:
            return self.statuses[-1][1] if self.statuses else None

    def close(self) -> None:
        self._keep.clear()
        self.session.close()


def wait(pred, timeout: float, what: str, run: PosedRun | None = None):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        if run is not None and run.proc.poll() is not None:
            raise AssertionError(f"the daemon exited ({run.proc.returncode}) while waiting for {what}: "
                                 + (run.dir / "err.log").read_text()[-2000:])
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def posed_cli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    """A ``posed`` command as a user types it."""
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)
