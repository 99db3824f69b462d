"""The daemon's web stage on a bus it cannot reach (issue 34 item 7: on the shipped TLS bus it never connected,
logged nothing and answered an empty history while falls were unacknowledged): after 10 s the page's snapshot
carries the reason and the fix (the banner), /api/history answers 502 with them instead of an empty list, the
status shows the web stage's bus_connected false, and one web_cannot_connect line says why. The real supervisor
and web stage processes; nothing listens on the daemon's endpoint, as when the session cannot be opened."""

from __future__ import annotations

import http.client
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.daemon.zenoh_util import free_port
from tests.viz.browser import Browser

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))


def _statuses(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip().endswith("}")]


def _get(port: int, path: str):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("GET", path)
    r = conn.getresponse()
    body = r.read()
    conn.close()
    return r.status, body


def _snapshot(port: int) -> dict:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("GET", "/stream")
    r = conn.getresponse()
    line = r.fp.readline()
    conn.close()
    assert line.startswith(b"data: "), line
    return json.loads(line[6:])


@pytest.mark.timeout(120)
def test_a_web_stage_without_a_bus_says_so_on_the_page_in_the_status_and_the_log(tmp_path):
    port = free_port()
    status_file = tmp_path / "status.jsonl"
    cmd = [sys.executable, "-m", "tests.daemon.supervise_plan", str(status_file), "--web",
           "--set", "pipeline.status_period_s=0.2", "--set", f"web.port={port}",
           "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", "--set", f"pipeline.state_dir={tmp_path}"]
    with open(tmp_path / "out.log", "w") as out:
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        web = {}
        while time.monotonic() < deadline:
            st = _statuses(status_file)
            web = st[-1]["stages"].get("web", {}) if st else {}
            if web.get("bus_connected") is False:
                break
            assert proc.poll() is None, (tmp_path / "out.log").read_text()[-3000:]
            time.sleep(0.2)
        assert web.get("bus_connected") is False, web
        status, body = _get(port, "/api/history")
        answer = json.loads(body)
        assert status == 502 and "not connected to the robot's bus" in answer["error"], answer
        assert "events" not in answer                     # never an empty list that reads as "no falls"
        snap = _snapshot(port)
        assert snap["bus"]["connected"] is False and snap["bus"]["reason"] and "deploy/zenoh" in snap["bus"]["fix"]
        with Browser(tmp_path / "profile") as b:          # what a caregiver opening the page sees
            b.open(f"http://127.0.0.1:{port}/")
            banner = b.wait_for("(() => { const e = document.getElementById('bus'); "
                                "return e && !e.hidden && e.textContent; })()", 20, "the bus banner")
            history = b.wait_for("document.getElementById('history').textContent", 20, "the history table")
            b.screenshot(ARTIFACTS / "web_no_bus.png")
        assert "Not connected to the robot" in banner and "Falls are NOT shown" in banner
        assert "no fall events stored" not in history and "not connected" in history
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(30)
    lines = [json.loads(x) for x in (tmp_path / "out.log").read_text().splitlines() if x.startswith("{")]
    cannot = [r for r in lines if r.get("event") == "web_cannot_connect"]
    assert len(cannot) == 1 and cannot[0]["fix"], cannot


def test_the_page_says_when_the_robot_cannot_store_fall_events(tmp_path):
    """issue 34 item 2: a state directory that fails is reported on the web view too, not only in the status."""
    import threading

    from posed.client.types import Status
    from posed.viz.web.hub import Hub
    from posed.viz.web.server import WebServer

    class _Robot:
        def ack(self, event_id):
            return True

        def history(self):
            return []

    hub = Hub("r")
    status = {"format": "posed.status", "robot": "r", "state": "running", "fps": 10.0, "drops": 0, "restarts": 0,
              "latency_ms": {"p95": 20.0}, "camera": {"state": "open"}, "events": {"unacknowledged": 2},
              "storage": {"state": "degraded", "unstored_events": 29, "fallback": "/run/posed/u.jsonl",
                          "reason": "cannot open the event journal: disk full", "fix": "free disk space"}}
    hub.on_status("r", Status.from_json(status))
    assert hub.snapshot()["status"]["storage"]["unstored_events"] == 29
    server = WebServer(hub, _Robot(), "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    try:
        with Browser(tmp_path / "profile") as b:
            b.open(f"http://127.0.0.1:{server.server_address[1]}/")
            text = b.wait_for("(() => { const e = document.getElementById('storage'); "
                              "return e && !e.hidden && e.textContent; })()", 20, "the storage banner")
            b.screenshot(ARTIFACTS / "web_storage_degraded.png")
    finally:
        server.shutdown()
        server.server_close()
    assert "cannot store fall events" in text and "29 kept in memory" in text and "/run/posed/u.jsonl" in text
    status["storage"] = {"state": "ok", "unstored_events": 0, "fallback": "/run/posed/u.jsonl"}
    hub.on_status("r", Status.from_json(status))
    assert hub.snapshot()["status"]["storage"] is None
