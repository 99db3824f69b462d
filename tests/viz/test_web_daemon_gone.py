"""A fall monitor must never look healthy when it is not: when the daemon stops (SIGTERM), goes silent (no status
and no pose for a few status periods) or the bus cannot be reached, the server pushes an explicit verdict
(``robot``: state, why, since when) and the page shows a red bar "posed on ROBOT is not running since ...",
the "live" badge becomes "NOT LIVE", the stale status and skeleton are greyed with their age; all of it
clears when the daemon is back.

The first test is the whole chain: a real daemon (`posed run` replaying the real squat video), the real hub
and server on a real Zenoh client session (127.0.0.1, no multicast scouting), a real headless Chromium that
stays open through the kill and the restart. The others drive the real hub and server with a clock of their
own."""

from __future__ import annotations

import http.client
import json
import os
import queue
import subprocess
import threading
import time
from pathlib import Path

import pytest

from posed.client.types import Status
from posed.commands._child import free_endpoint, run_command, stop
from posed.viz.web.hub import STALE_MIN_S, START_GRACE_S, Hub
from posed.viz.web.server import WebServer
from tests.viz.browser import Browser

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
ROBOT = "gonebot"
BAR = "(() => { const e = document.getElementById('down'); return e && !e.hidden && e.textContent; })()"
CONN = "document.getElementById('conn').textContent"


class _Stream:
    """The server's event stream as a page reads it: every message, in order, on a queue."""

    def __init__(self, port: int) -> None:
        self.messages: queue.Queue = queue.Queue()
        self.conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        self.conn.request("GET", "/stream")
        self.response = self.conn.getresponse()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            for line in self.response.fp:
                if line.startswith(b"data: "):
                    self.messages.put(json.loads(line[6:]))
        except (OSError, ValueError):
            pass

    def drain(self) -> None:
        """Forget what came so far: a verdict sent before now (a 'down, starting' while the daemon came up, when
        its first status arrived before its liveliness token) is not an answer to what happens next."""
        while True:
            try:
                self.messages.get_nowait()
            except queue.Empty:
                return

    def wait(self, test, timeout: float, what: str) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"no {what} within {timeout:.0f} s")
            try:
                m = self.messages.get(timeout=left)
            except queue.Empty:
                continue
            if test(m):
                return m

    def close(self) -> None:
        self.conn.close()


def _robot(state: str, why=None):
    return lambda m: m.get("type") == "robot" and m["state"] == state and (why is None or m["why"] == why)


def _serve(hub: Hub, link):
    server = WebServer(hub, link, "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    return server


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_killing_the_daemon_turns_the_page_red_and_its_return_clears_it(tmp_path, shared_data):
    from posed.client import PosedClient
    from posed.viz.web.bus import RobotLink

    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    endpoint, state = free_endpoint(), tmp_path / "state"
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={state}", f'zenoh.listen=["{endpoint}"]',
                       "pipeline.status_period_s=0.5", "logging.format=json"], source=f"file:{video}?loop=true")
    logs, procs = [], []

    def start_daemon():
        log = open(tmp_path / f"daemon{len(logs)}.log", "w")
        logs.append(log)
        procs.append(subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT))
        return procs[-1]

    daemon = start_daemon()
    hub = Hub(ROBOT)
    client = PosedClient.connect(endpoint, wait_s=120)
    server = browser = stream = None
    try:
        link = RobotLink(client, hub, ROBOT)
        server = _serve(hub, link)
        stream = _Stream(server.server_address[1])
        browser = Browser(tmp_path / "profile")
        browser.open(server.url)
        browser.wait_for(f"window.posedView && posedView.poses >= 3 && {CONN} === 'live'", 240,
                         "the live page with poses")
        assert hub.robot_state()["state"] == "up"
        assert browser.js(BAR) is False and not browser.js("document.body.classList.contains('stale')")
        browser.screenshot(ARTIFACTS / "web_daemon_alive.png")

        stream.drain()
        daemon.terminate()                      # as systemd stops it, or as it dies
        t_kill = time.time()
        daemon.wait(60)
        down = stream.wait(_robot("down"), 20, "'down' verdict after the daemon stopped")
        # gone by Zenoh liveliness, or silent by the clock: either way said, with the time it was last heard
        assert down["why"] in ("gone", "silent"), down
        assert t_kill - 5.0 <= down["since_unix"] <= t_kill + 1.0, (down, t_kill)
        bar = browser.wait_for(BAR, 15, "the red bar on the page")
        assert f"posed on {ROBOT}" in bar and "falls are NOT being detected" in bar, bar
        assert browser.js(CONN) == "NOT LIVE"
        assert browser.js("document.body.classList.contains('stale')")
        assert "ago" in browser.js("document.getElementById('st-age').textContent")
        assert "ago" in browser.js("document.getElementById('angles-age').textContent")
        assert browser.js("getComputedStyle(document.getElementById('st-state')).color") == "rgb(158, 158, 158)"
        assert browser.js("document.getElementById('pose-note').textContent") == "not live"
        browser.screenshot(ARTIFACTS / "web_daemon_gone.png")

        start_daemon()                          # back: the bar clears, the badge says live again
        up = stream.wait(_robot("up"), 240, "'up' verdict after the restart")
        assert up["status_at"] is not None and up["last_heard_unix"] > down["since_unix"] + 1.0, (up, down)
        browser.wait_for(f"{BAR} === false && {CONN} === 'live'", 60, "the bar cleared and the page live again")
        # what is shown now is the new run's: never the old run's last status shown as live
        assert browser.js("document.getElementById('st-state').textContent") in ("starting", "running")
        assert not browser.js("document.body.classList.contains('stale')")
        assert browser.js("document.getElementById('st-age').textContent") == ""
        browser.screenshot(ARTIFACTS / "web_daemon_back.png")
    finally:
        if browser is not None:
            browser.close()
        if stream is not None:
            stream.close()
        if server is not None:
            server.shutdown()
            server.server_close()
        client.close()
        for p in procs:
            stop(p, 20.0)
        for log in logs:
            log.close()


class _Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class _NoHistory:
    def ack(self, event_id):
        raise AssertionError("no acknowledgement here")

    def history(self):
        return []


def _status() -> Status:
    return Status.from_json({"state": "running", "fps": 5.0, "camera": {"state": "open"}}, "r")


def test_a_silent_robot_is_down_after_a_few_status_periods_and_up_again_with_its_next_status():
    """Stuck (no status, no pose) though liveliness never said gone: down, 'silent', since the last status."""
    mono, wall = _Clock(), _Clock()
    hub = Hub("r", monotonic=mono, wall=wall)
    server = _serve(hub, _NoHistory())
    try:
        for _ in range(4):                      # a status every 2 s: silent after 5 periods (10 s)
            hub.on_status("r", _status())
            mono.t += 2.0
            wall.t += 2.0
        hub.on_alive(True)
        last = wall.t
        hub.on_status("r", _status())
        assert hub.stale_after_s() == pytest.approx(10.0)
        stream = _Stream(server.server_address[1])
        snap = stream.wait(lambda m: m["type"] == "snapshot", 10, "snapshot")
        assert snap["robot_state"]["state"] == "up"
        mono.t += 9.0                           # not yet
        time.sleep(1.2)
        assert hub.robot_state()["state"] == "up"
        mono.t += 2.0
        wall.t += 11.0
        down = stream.wait(_robot("down", "silent"), 5, "the silent verdict, pushed by the server's clock")
        assert down["since_unix"] == last and down["status_at"] == last
        hub.on_status("r", _status())
        stream.wait(_robot("up"), 5, "up again with the next status")
        stream.close()
    finally:
        server.shutdown()
        server.server_close()


def test_gone_bus_and_never_heard_are_all_down(tmp_path):
    mono, wall = _Clock(), _Clock()
    hub = Hub("r", monotonic=mono, wall=wall)
    assert hub.robot_state()["state"] == "waiting"          # just opened: a moment to hear from it
    mono.t += max(START_GRACE_S, STALE_MIN_S) + 1
    never = hub.robot_state()          # nothing at all since the page opened
    assert never["state"] == "down" and never["why"] == "silent" and never["last_heard_unix"] is None
    hub.on_alive(True)
    hub.on_status("r", _status())
    assert hub.robot_state()["state"] == "up"
    hub.on_alive(False)                                      # liveliness: the daemon's token went away
    gone = hub.robot_state()
    assert gone["state"] == "down" and gone["why"] == "gone"
    mono.t += 3.0
    hub.on_alive(True)              # its token is back, no word from the new run yet: not up, starting
    starting = hub.robot_state()
    assert starting["state"] == "down" and starting["why"] == "starting"
    hub.on_status("r", _status())
    assert hub.robot_state()["state"] == "up"
    hub.on_bus(False, "no route to tcp/127.0.0.1:1", "check zenoh.connect")   # this side has no bus
    assert hub.robot_state()["why"] == "bus"
    # the page: a robot never heard from says so in the red bar, and the badge is not "live"
    hub2 = Hub("r2", monotonic=mono, wall=wall)
    mono.t += START_GRACE_S + 1
    server = _serve(hub2, _NoHistory())
    try:
        with Browser(tmp_path / "profile") as b:
            b.open(server.url)
            bar = b.wait_for(BAR, 20, "the red bar")
            assert "posed on r2 has not been heard from since this page opened" in bar
            assert "falls are NOT being detected" in bar
            assert b.js(CONN) == "NOT LIVE"
            assert "none can arrive" in b.js("document.getElementById('events').textContent")
    finally:
        server.shutdown()
        server.server_close()
