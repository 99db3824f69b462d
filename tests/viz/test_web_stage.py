"""The live view as a stage of the daemon (``web.enabled``): a real `posed run` replaying a real fall
recording serves the page itself; the page's stream carries the poses and the fall, its ack endpoint
acknowledges the event in the daemon's journal; the stage is listed in the status; a port already in use
leaves the pipeline running."""

from __future__ import annotations

import http.client
import json
import socket
import subprocess
import time
from pathlib import Path

import pytest

from posed.commands._child import free_endpoint, run_command, stop
from posed.daemon.outbox.journal import EventJournal

ROOT = Path(__file__).resolve().parents[2]
ROBOT = "webstage"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _daemon(tmp_path: Path, shared_data: Path, port: int):
    labels = json.loads((shared_data / "falls" / "urfd_dev" / "labels.json").read_text())["camera"]
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    state = tmp_path / "state"
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={state}", f'zenoh.listen=["{free_endpoint()}"]',
                       "logging.format=json", "web.enabled=true", f"web.port={port}",
                       f"falls.camera_height_m={labels['camera_height_m']}",
                       f"falls.camera_tilt_deg={labels['camera_tilt_deg']}",
                       f"falls.camera_roll_deg={labels['camera_roll_deg']}"], source=f"file:{rec}?loop=true")
    log = open(tmp_path / "daemon.log", "w")
    return subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT), state, log


def _stream_messages(port: int, until, timeout: float) -> list[dict]:
    """Read the page's event stream until ``until(messages)`` holds."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            conn.request("GET", "/stream", headers={"Host": f"127.0.0.1:{port}"})
            r = conn.getresponse()
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)
    assert r.status == 200 and r.getheader("Content-Type") == "text/event-stream"
    got: list[dict] = []
    try:
        while time.monotonic() < deadline:
            try:
                line = r.fp.readline()
            except TimeoutError:
                continue
            if line.startswith(b"data: "):
                got.append(json.loads(line[6:]))
                if until(got):
                    return got
    finally:
        conn.close()
    raise AssertionError(f"the stream did not show it in {timeout} s; kinds seen: {sorted({m.get('type') for m in got})}")


def _kinds(msgs: list[dict]) -> set:
    return {m.get("type") for m in msgs}


@pytest.mark.slow
def test_daemon_serves_the_page_with_poses_and_the_fall_and_acks_through_it(tmp_path, shared_data):
    port = _free_port()
    proc, state, log = _daemon(tmp_path, shared_data, port)
    try:
        conn = None
        msgs = _stream_messages(port, lambda got: any(m.get("type") == "event" for m in got), 240)
        assert "pose" in _kinds(msgs), _kinds(msgs)
        event = next(m for m in msgs if m.get("type") == "event")
        event_id = event["id"]
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        conn.request("GET", "/", headers={"Host": f"127.0.0.1:{port}"})
        page = conn.getresponse()
        body = page.read().decode()
        assert page.status == 200 and "<img" not in body.lower()
        deadline = time.monotonic() + 60
        while True:
            conn.request("POST", "/api/ack", body=json.dumps({"id": event_id, "by": "Anna (daughter)"}),
                         headers={"Host": f"127.0.0.1:{port}", "Content-Type": "application/json",
                                  "X-Posed": "ack"})
            reply = conn.getresponse()
            answer = json.loads(reply.read() or b"{}")
            if (reply.status == 200 and answer.get("confirmed")) or time.monotonic() > deadline:
                break
            time.sleep(1.0)
        assert reply.status == 200 and answer["confirmed"], answer
        with EventJournal(state / "events.sqlite3", readonly=True) as journal:
            stored = [s for s in journal.query() if s.event.id == event_id]
        assert stored and any(s.acked_at is not None for s in stored)
        assert {s.acked_by for s in stored if s.acked_at is not None} == {"Anna (daughter)"}   # who, as typed
    finally:
        if conn is not None:
            conn.close()
        stop(proc, 20.0)
        log.close()
    text = (tmp_path / "daemon.log").read_text()
    assert '"web_serving"' in text and proc.returncode == 0, text[-3000:]


@pytest.mark.slow
def test_a_port_in_use_leaves_the_pipeline_running(tmp_path, shared_data):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc, state, log = _daemon(tmp_path, shared_data, port)
        try:
            deadline = time.monotonic() + 240
            text = ""
            while time.monotonic() < deadline:
                text = (tmp_path / "daemon.log").read_text()
                if '"daemon_ready"' in text and '"web_cannot_serve"' in text:
                    break
                assert proc.poll() is None, text[-3000:]
                time.sleep(0.5)
            assert '"daemon_ready"' in text and '"web_cannot_serve"' in text, text[-3000:]
            assert proc.poll() is None
        finally:
            stop(proc, 20.0)
            log.close()
    assert proc.returncode == 0
