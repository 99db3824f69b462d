"""The real daemon (`posed run --source v4l2:/dev/video0`) on a webcam that misbehaves, at the hardware edge:
OpenCV's capture is replaced, in the daemon's own processes, by a scripted camera (a ``sitecustomize`` on the
daemon's PYTHONPATH; this machine has no webcam). The camera sends real frames, then black frames for 7 s
(a covered lens), then real frames again; later the source's read raises an exception that is not a hal error
(a driver or source bug). The daemon must say it is blind and why (blank frames, uncover the lens), and come
back; the unexpected exception must close and reopen the camera, not kill the capture stage (which the
supervisor restarted until it escalated, exit 70)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.daemon.zenoh_util import free_port

ROOT = Path(__file__).resolve().parents[2]

FAKE = '''
import os, sys, threading, time
import importlib.abc, importlib.util

STATE = {"sent": 0, "reads": 0, "raised": 0}
LOCK = threading.Lock()
IMAGE = os.environ["POSED_TEST_FAKE_IMAGE"]


def _install(mod):
    import cv2
    import numpy as np

    img = cv2.resize(cv2.imread(IMAGE), (640, 480))

    class Cap:
        def isOpened(self):
            return True

        def set(self, prop, value):
            return True

        def get(self, prop):
            return {cv2.CAP_PROP_FRAME_WIDTH: 640.0, cv2.CAP_PROP_FRAME_HEIGHT: 480.0,
                    cv2.CAP_PROP_FPS: 30.0}.get(prop, 0.0)

        def read(self):
            time.sleep(1 / 30)
            with LOCK:
                n = STATE["sent"]
                STATE["sent"] += 1
            if 30 <= n < 240:
                return True, np.zeros((480, 640, 3), np.uint8)           # a covered lens
            noise = np.random.default_rng(n).integers(-2, 3, img.shape)
            return True, np.clip(img.astype(np.int16) + noise, 0, 255).astype(np.uint8)

        def release(self):
            pass

    mod.opencv_capture = lambda device, api: Cap()
    real_read = mod.V4L2Source._read

    def _read(self, timeout_s):
        with LOCK:
            if STATE["reads"] >= 60 and STATE["raised"] < 2:
                STATE["raised"] += 1
                raise ValueError("simulated driver bug")
        frame = real_read(self, timeout_s)
        with LOCK:
            STATE["reads"] += 1
        return frame

    mod.V4L2Source._read = _read


class Hook(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != "posed.hal.v4l2":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        run = spec.loader.exec_module

        def exec_module(mod):
            run(mod)
            _install(mod)

        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, Hook())
'''


def _events(path: Path) -> list[dict]:
    out = []
    for line in path.read_text(errors="replace").splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:
            pass
    return out


def _watching_again(events: list[dict]) -> bool:
    """After the last ``capture_failed``: the camera opened again and the daemon runs at a frame rate."""
    names = [e.get("event") for e in events]
    if "capture_failed" not in names:
        return False
    last = len(names) - 1 - names[::-1].index("capture_failed")
    after = events[last:]
    opened = [i for i, e in enumerate(after) if e.get("event") == "camera_open"]
    return bool(opened) and any(e.get("event") == "stats" and e.get("state") == "running" and (e.get("fps") or 0) > 0
                                for e in after[opened[0]:])


def test_daemon_says_blank_frames_and_survives_a_failing_read(tmp_path, shared_data):
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(FAKE)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
           "POSED_TEST_FAKE_IMAGE": str(shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg")}
    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", "v4l2:/dev/video0",
           "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", "--set", f"pipeline.state_dir={tmp_path / 'state'}",
           "--set", "logging.stats_period_s=1", "--set", "logging.format=json"]
    out = tmp_path / "out.log"
    with open(out, "w") as fo, open(tmp_path / "err.log", "w") as fe:
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=fo, stderr=fe, start_new_session=True)
    try:
        deadline = time.monotonic() + 150
        while time.monotonic() < deadline and proc.poll() is None:
            if _watching_again(_events(out)):
                break
            time.sleep(0.5)
        time.sleep(1.0)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        code = proc.wait(30)
    events = _events(out)
    names = [e.get("event") for e in events]
    blind = [e for e in events if e.get("event") == "blind"]
    assert blind, f"never blind while the camera sent black frames; events: {sorted(set(names))}"
    assert "blank frames" in blind[0]["reason"] and "black" in blind[0]["reason"], blind[0]
    assert "uncover the camera's lens" in blind[0]["fix"], blind[0]
    assert "blind_ended" in names                                   # frames again once uncovered
    failed = [e for e in events if e.get("event") == "capture_failed"]
    assert failed and "simulated driver bug" in failed[0]["error"], names
    assert _watching_again(events), names                          # reopened, and frames flow again
    assert "stage_dead" not in names and "stage_restarted" not in names, \
        [e for e in events if e.get("event") in ("stage_dead", "stage_restarted")]
    assert code == 0, (code, (tmp_path / "err.log").read_text()[-2000:])
