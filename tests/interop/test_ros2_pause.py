"""docs/ros2.md's privacy-pause node as written, with rclpy and std_srvs replaced by stand-ins (no ROS 2 here),
against a real ``posed run`` replaying the real squat video on 127.0.0.1: a SetBool request ``true`` pauses the
robot (its status says ``paused``, by the node's ``BY``), ``false`` resumes it, and a request to a robot that
does not answer comes back ``success: false`` with the client's reason."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.daemon.privacy_util import SQUAT, PosedRun, Viewer, wait
from tests.daemon.zenoh_util import free_port

DOC = Path(__file__).resolve().parents[2] / "docs" / "ros2.md"

# rclpy.spin answers the requests listed in FAKE_REQUESTS (JSON booleans), one at a time, printing each response
FAKE_ROS = {
    "rclpy/__init__.py": '''
import json, os
def init():
    pass
def spin(node):
    [(srv_type, name, callback)] = node._services
    assert name == "posed/privacy_pause" and srv_type.__name__ == "SetBool"
    for data in json.loads(os.environ["FAKE_REQUESTS"]):
        response = callback(srv_type.Request(data=data), srv_type.Response())
        print("RESPONSE", json.dumps({"success": response.success, "message": response.message}), flush=True)
''',
    "rclpy/node.py": '''
class Node:
    def __init__(self, name):
        self.name, self._services = name, []
    def create_service(self, srv_type, name, callback):
        self._services.append((srv_type, name, callback))
''',
    "std_srvs/__init__.py": "",
    "std_srvs/srv.py": '''
class SetBool:
    class Request:
        def __init__(self, data=False):
            self.data = data
    class Response:
        def __init__(self):
            self.success, self.message = False, ""
''',
}


def _node(tmp_path: Path, endpoint: str, robot: str, requests: list[bool]) -> list[dict]:
    [code] = [b for b in re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S) if "SetBool" in b]
    for rel, text in FAKE_ROS.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    code = code.replace("tcp/127.0.0.1:7447", endpoint).replace('ROBOT = "kitchen"', f'ROBOT = "{robot}"')
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=90,
                         env={**os.environ, "PYTHONPATH": str(tmp_path), "FAKE_REQUESTS": json.dumps(requests)})
    assert out.returncode == 0, out.stderr[-2000:]
    return [json.loads(line.split(" ", 1)[1]) for line in out.stdout.splitlines() if line.startswith("RESPONSE ")]


@pytest.mark.timeout(300)
def test_the_ros2_privacy_node_pauses_and_resumes_a_real_robot(tmp_path, shared_data):
    run = PosedRun(tmp_path, "d", f"{shared_data / SQUAT}?loop=true", "rospause", free_port())
    viewer = None
    try:
        viewer = Viewer(run.endpoint, "rospause")
        wait(lambda: viewer.poses_between(0) >= 3, 120, "poses before the pause", run)
        [paused] = _node(tmp_path, run.endpoint, "rospause", [True])
        assert paused["success"] is True and re.fullmatch(r"paused until \d\d:\d\d", paused["message"]), paused
        st = wait(lambda: next((s for s in reversed(viewer.statuses_since(0)) if s["state"] == "paused"), None),
                  10, "a status saying paused", run)
        assert st["privacy"]["by"] == "voice" and 800 < st["privacy"]["remaining_s"] <= 900, st["privacy"]
        [resumed] = _node(tmp_path, run.endpoint, "rospause", [False])
        assert resumed == {"success": True, "message": "watching again"}
        wait(lambda: (viewer.last_status() or {}).get("state") == "running", 20, "running again", run)
        assert [e["ended"] for e in run.events("privacy_pause_ended")] == ["resumed"]
        # a robot that does not answer: the node says so instead of claiming a pause
        [nobody] = _node(tmp_path, run.endpoint, "nosuchrobot", [True])
        assert nobody["success"] is False and "nosuchrobot" in nobody["message"], nobody
    finally:
        if viewer is not None:
            viewer.close()
        run.stop()
