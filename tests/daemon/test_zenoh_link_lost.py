"""The router a client-mode daemon is connected to goes away, and comes back: Zenoh drops what is put meanwhile
without an error, so the daemon logs it (zenoh_link_lost, a warning naming the endpoint and the fix), and
zenoh_link_back when the router is there again. A real daemon, a real router on 127.0.0.1."""

from __future__ import annotations

import json
import signal
import time

from tests.daemon.test_run_e2e import posed_run
from tests.daemon.zenoh_util import free_port, router

SQUAT = "reference/tfjs_pose_squats/pose_squats.mp4"


def _events(path) -> list[dict]:
    out = []
    for line in path.read_text().splitlines():
        try:
            obj = json.loads(line)
        except ValueError:
            continue
        if isinstance(obj, dict):
            out.append(obj)
    return out


def _wait_event(tmp_path, name: str, timeout: float, proc) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for e in _events(tmp_path / "err.log") + _events(tmp_path / "out.log"):
            if e.get("event") == name:
                return e
        assert proc.poll() is None, (tmp_path / "err.log").read_text()[-3000:]
        time.sleep(0.2)
    raise AssertionError(f"no {name} within {timeout} s: " + (tmp_path / "err.log").read_text()[-3000:])


def test_a_lost_router_is_logged_and_its_return_too(tmp_path, shared_data):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    r = router(endpoint)
    proc = posed_run(tmp_path, f"{shared_data / SQUAT}?loop=true", "robot_id=linkbot", "zenoh.mode=client",
                     f"zenoh.connect=[{endpoint}]")
    try:
        _wait_event(tmp_path, "zenoh_open", 60.0, proc)
        time.sleep(2.5)                       # a count with the router in it
        r.close()
        lost = _wait_event(tmp_path, "zenoh_link_lost", 30.0, proc)
        assert lost.get("level") == "warning" and endpoint in lost["fix"], lost
        assert "fall events are kept" in lost["fix"], lost
        r = router(endpoint)
        _wait_event(tmp_path, "zenoh_link_back", 60.0, proc)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except Exception:
                proc.kill()
        r.close()
