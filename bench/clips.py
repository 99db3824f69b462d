"""Every real clip of the shared data through ``posed run`` as a camera would give it (issue 39): default config,
paced, ``pipeline.stop_at_end``; a Zenoh router on 127.0.0.1 in this process with subscribers on the daemon's
topics before the daemon starts, so no message is missed. Per clip: its size and rate, the working size the
daemon used, the poses it should publish (the frames the capture stage takes at ``pipeline.target_fps``), the
poses and landmarks it published, with a person, whether it was ever blind, and its exit status.

Run: ``posed bench pipeline --clips [--json]``. :func:`run_to_end` is the harness the daemon tests use too.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from posed.bench.notify_socket import NotifySocket

CLIPS = ("multi_person/s2d_enter.mp4", "multi_person/bend_hand.mp4", "multi_person/store_aisle.gif",
         "pose2sim_demo/balancing/cam01.mp4", "pose2sim_demo/balancing/cam02.mp4",
         "pose2sim_demo/balancing/cam03.mp4", "pose2sim_demo/balancing/cam04.mp4",
         "tfjs_pose_squats/pose_squats.mp4")
KEYS = ("pose", "landmarks", "status", "events/fall")


@dataclass
class Run:
    """What one ``posed run`` to its end did: exit code, JSON log lines, stderr, the messages per topic key,
    and the STATUS= lines it sent to systemd."""

    code: int
    log: list[dict]
    stderr: str
    got: dict[str, list[dict]] = field(default_factory=dict)
    notify: list[str] = field(default_factory=list)

    def events(self, name: str) -> list[dict]:
        return [x for x in self.log if x.get("event") == name]


def run_to_end(workdir: Path, source: str, *overrides: str, robot: str = "clip", timeout_s: float = 150.0,
               keys: tuple[str, ...] = KEYS, cwd: Path | None = None) -> Run:
    """``posed run --source SOURCE`` (paced unless an override says otherwise, stopping at the end) joined to a
    router in this process; what it published per key (subscribed before it started), its log, stderr, and
    STATUS= lines."""
    import zenoh

    from posed.client import session_config
    from posed.commands._child import free_endpoint

    rep = free_endpoint()
    router = zenoh.open(session_config("router", listen=[rep]))
    lock = threading.Lock()
    got: dict[str, list[dict]] = {k: [] for k in keys}
    sock = str(workdir / "notify.sock")
    notify = NotifySocket(sock)

    def keep(into: list[dict]):
        def on(sample) -> None:
            with lock:
                into.append(json.loads(sample.payload.to_string()))
        return on

    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", source,
           "--set", f"pipeline.state_dir={workdir / 'state'}", "--set", "logging.format=json",
           "--set", f"robot_id={robot}", "--set", "pipeline.stop_at_end=true",
           "--set", "pipeline.status_period_s=0.5", "--set", f"zenoh.listen=[{free_endpoint()}]",
           "--set", f"zenoh.connect=[{rep}]"]
    for o in overrides:
        cmd += ["--set", o]
    out, err = workdir / "out.log", workdir / "err.log"
    try:
        with zenoh.open(session_config("client", connect=[rep])) as s:
            subs = [s.declare_subscriber(f"posed/{robot}/{k}", keep(got[k])) for k in keys]
            with open(out, "w") as fo, open(err, "w") as fe:
                proc = subprocess.Popen(cmd, cwd=cwd, stdout=fo, stderr=fe,
                                        env={**os.environ, "NOTIFY_SOCKET": sock})
                try:
                    code = proc.wait(timeout=timeout_s)
                finally:
                    if proc.poll() is None:
                        proc.kill()
                        proc.wait(10)
            time.sleep(0.3)
            del subs
    finally:
        router.close()
        notify.close()
    log = []
    for line in (out.read_text() + "\n" + err.read_text()).splitlines():
        if line.startswith("{"):
            try:
                log.append(json.loads(line))
            except ValueError:
                pass
    with lock:
        return Run(code, log, err.read_text(), {k: list(v) for k, v in got.items()},
                   notify.texts("STATUS="))


def frames_taken(n_frames: int, fps: float, target_fps: float = 10.0) -> int:
    """How many of ``n_frames`` at ``fps`` the capture stage takes at ``target_fps`` (its own thinner)."""
    from posed.daemon.stages.capture import _Thinner

    th = _Thinner(target_fps)
    return sum(th.take(i / fps) for i in range(n_frames))


def measure(shared: Path, clips: tuple[str, ...] = CLIPS) -> list[dict]:
    """One row per clip (see the module's docstring)."""
    import cv2

    rows = []
    for clip in clips:
        path = shared / "reference" / clip
        cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        fps, n = cap.get(cv2.CAP_PROP_FPS), int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        ok, image = cap.read()
        cap.release()
        if not ok:
            raise RuntimeError(f"{path}: no frame could be read")
        with tempfile.TemporaryDirectory(prefix="posed-clip-") as tmp:
            t0 = time.monotonic()
            run = run_to_end(Path(tmp), f"file:{path}")
            took = time.monotonic() - t0
        cams = [s["camera"] for s in run.got["status"] if "scale" in s.get("camera", {})]
        expected = frames_taken(n, fps)
        poses = run.got["pose"]
        rows.append({
            "clip": clip, "size": f"{image.shape[1]}x{image.shape[0]}", "fps": round(fps, 2), "frames": n,
            "working": f"{cams[-1]['working_width']}x{cams[-1]['working_height']}" if cams else None,
            "poses_expected": expected, "poses": len(poses), "poses_with_person": sum(1 for p in poses if p.get("ok")),
            "landmarks_with_person": sum(1 for m in run.got["landmarks"] if m.get("landmarks")),
            "published_fraction": round(len(poses) / expected, 3) if expected else None,
            "ever_blind": any(s.get("state") == "blind" for s in run.got["status"]), "exit": run.code,
            "run_s": round(took, 1),
            "target_met": run.code == 0 and expected > 0 and len(poses) >= 0.9 * expected,
        })
    return rows
