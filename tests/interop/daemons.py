"""Real ``posed run`` processes for the interop tests, each joining a zenoh-python session in router mode (the
stand-in for zenohd) on 127.0.0.1, multicast scouting off; and a collector of every sample on posed/ROBOT/**."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from tests.daemon.zenoh_util import free_port

ROOT = Path(__file__).resolve().parents[2]
SQUAT = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"
URFD = Path("falls") / "urfd_dev"
FALL_CLIP = "urfd_02_fall"       # the person stays in view 1.2 s after the impact (labels.json), so a fall
                                 # event comes; urfd_00 loses them 0.17 s after it


def fall_overrides(shared_data: Path, clip: str = FALL_CLIP) -> list[str]:
    """The falls settings for a UR Fall Detection clip: its camera geometry from labels.json and every frame
    (30 fps) through the pipeline."""
    labels = json.loads((shared_data / URFD / "labels.json").read_text())
    cam = labels["camera"]
    assert any(c["clip"] == clip and c["label"] == "fall" for c in labels["clips"])
    return [f"falls.camera_height_m={cam['camera_height_m']}", f"falls.camera_tilt_deg={cam['camera_tilt_deg']}",
            f"falls.camera_roll_deg={cam['camera_roll_deg']}", "pipeline.target_fps=30"]


class Daemon:
    """One ``posed run`` (robot ``robot``) listening on its own port and connecting to ``router``."""

    def __init__(self, tmp: Path, robot: str, source: Path, router: str, *overrides: str,
                 state_dir: Path | None = None, config: Path | None = None, python: str = sys.executable,
                 cwd: Path = ROOT, env: dict | None = None) -> None:
        """``python``, ``cwd`` and ``env``: another installation of posed (an installed wheel, run from a folder
        that is not the checkout)."""
        self.robot = robot
        self.cwd = cwd
        self.env = env
        self.dir = tmp / robot
        self.dir.mkdir(parents=True, exist_ok=True)
        self.state_dir = state_dir or self.dir / "state"
        self.listen = f"tcp/127.0.0.1:{free_port()}"
        self.cmd = [python, "-m", "posed.cli", "run", "--source", f"file:{source}",
                    "--set", f"pipeline.state_dir={self.state_dir}", "--set", "logging.format=json",
                    "--set", f"robot_id={robot}", "--set", f"zenoh.listen=[{self.listen}]",
                    "--set", f"zenoh.connect=[{router}]", "--set", "source.realtime=false"]
        if config is not None:
            self.cmd[4:4] = ["--config", str(config)]
        for o in overrides:
            self.cmd += ["--set", o]
        self.proc: subprocess.Popen | None = None
        self.runs = 0

    def start(self) -> Daemon:
        self.runs += 1
        self.proc = subprocess.Popen(self.cmd, cwd=self.cwd, env=self.env,
                                     stdout=open(self.dir / f"out{self.runs}.log", "w"),
                                     stderr=open(self.dir / f"err{self.runs}.log", "w"))
        return self

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)

    def stop(self) -> int | None:
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                return self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        return self.proc.wait(10)

    def log(self) -> str:
        return "\n".join((self.dir / f"{n}{self.runs}.log").read_text()[-3000:] for n in ("out", "err"))


class Collector:
    """Every sample on ``posed/<robots>/**``: (key, encoding, decoded JSON or the text)."""

    def __init__(self, session, robots: str = "*") -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[str, str, object]] = []
        self._sub = session.declare_subscriber(f"posed/{robots}/**", self._on)

    def _on(self, s) -> None:
        text = s.payload.to_string()
        try:
            value = json.loads(text)
        except ValueError:
            value = text
        with self.lock:
            self.samples.append((str(s.key_expr), str(s.encoding), value))

    def on(self, suffix: str) -> list:
        with self.lock:
            return [v for k, _, v in self.samples if k.endswith(suffix)]

    def all(self) -> list:
        with self.lock:
            return list(self.samples)


def wait_for(pred, timeout: float, what: str, daemon: Daemon | None = None):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        if daemon is not None and daemon.proc is not None and daemon.proc.poll() is not None:
            raise AssertionError(f"{daemon.robot} exited ({daemon.proc.returncode}) while waiting for {what}:\n"
                                 f"{daemon.log()}")
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


