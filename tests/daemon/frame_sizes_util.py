"""Run ``posed run`` on a source to its end (``pipeline.stop_at_end``) with a Zenoh router on 127.0.0.1 and a
subscriber on pose, landmarks, status and fall events, an sd_notify socket read like systemd; and real clips
made with cv2.VideoWriter from the shared test footage (other sizes and frame rates)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tests.daemon.harness import NotifyListener
from tests.daemon.zenoh_util import client, free_port, router

ROOT = Path(__file__).resolve().parents[2]


@dataclass
class Run:
    code: int
    log: list[dict]
    stderr: str
    got: dict[str, list[dict]] = field(default_factory=dict)
    notify: list[str] = field(default_factory=list)

    def events(self, name: str) -> list[dict]:
        return [x for x in self.log if x.get("event") == name]


def run_to_end(tmp_path: Path, source: str, *overrides: str, robot: str = "fs", timeout_s: float = 150.0,
               keys: tuple[str, ...] = ("pose", "landmarks", "status", "events/fall")) -> Run:
    """``posed run --source SOURCE`` (paced unless an override says otherwise) to its end; what it published
    per key, its JSON log lines, stderr text and the STATUS= lines it sent to systemd."""
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    lock = threading.Lock()
    got: dict[str, list[dict]] = {k: [] for k in keys}
    sock = str(tmp_path / "notify.sock")
    listener = NotifyListener(sock)

    def keep(into: list[dict]):
        def on(sample) -> None:
            with lock:
                into.append(json.loads(sample.payload.to_string()))
        return on

    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", source,
           "--set", f"pipeline.state_dir={tmp_path / 'state'}", "--set", "logging.format=json",
           "--set", f"robot_id={robot}", "--set", "pipeline.stop_at_end=true",
           "--set", "pipeline.status_period_s=0.5", "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]",
           "--set", f"zenoh.connect=[{rep}]"]
    for o in overrides:
        cmd += ["--set", o]
    out, err = tmp_path / "out.log", tmp_path / "err.log"
    try:
        with client(rep) as s:
            subs = [s.declare_subscriber(f"posed/{robot}/{k}", keep(got[k])) for k in keys]
            with open(out, "w") as fo, open(err, "w") as fe:
                proc = subprocess.Popen(cmd, cwd=ROOT, stdout=fo, stderr=fe,
                                        env={**os.environ, "NOTIFY_SOCKET": sock})
                try:
                    code = proc.wait(timeout=timeout_s)
                finally:
                    if proc.poll() is None:
                        proc.kill()
            time.sleep(0.3)
            del subs
    finally:
        r.close()
        listener.close()
    text = out.read_text() + "\n" + err.read_text()
    log = []
    for line in text.splitlines():
        if line.startswith("{"):
            try:
                log.append(json.loads(line))
            except ValueError:
                pass
    with lock:
        return Run(code, log, err.read_text(), {k: list(v) for k, v in got.items()},
                   [m for _, m in listener.messages if m.startswith("STATUS=")])


def read_frames(path: Path, n: int | None = None, step: int = 1) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    frames = []
    i = 0
    while n is None or len(frames) < n:
        ok, image = cap.read()
        if not ok:
            break
        if i % step == 0:
            frames.append(image)
        i += 1
    cap.release()
    return frames


def write_video(path: Path, frames: list[np.ndarray], fps: float) -> Path:
    """An MJPG AVI of ``frames`` at ``fps`` (what a webcam or a CCTV export gives)."""
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert vw.isOpened(), f"OpenCV cannot write {path}"
    for f in frames:
        assert f.shape[:2] == (h, w)
        vw.write(f)
    vw.release()
    return path


def frames_taken(n_frames: int, fps: float, target_fps: float = 10.0) -> int:
    """How many of ``n_frames`` at ``fps`` the capture stage takes at ``target_fps`` (its own thinner)."""
    from posed.daemon.stages.capture import _Thinner

    th = _Thinner(target_fps)
    return sum(th.take(i / fps) for i in range(n_frames))
