"""The live view in a real headless Chromium against real daemons (`posed run` replaying the real squat video,
then a real recording of a fall), through `posed web` and the Zenoh client: the skeleton moves, the fps is
shown, a fall appears and its acknowledge button acknowledges it in the daemon's journal. Screenshots go to
build/test-artifacts/. And the server's doors: token, Host header, the ack header, no path escapes."""

from __future__ import annotations

import http.client
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.commands._child import free_endpoint, run_command, stop
from posed.daemon.outbox.journal import EventJournal
from posed.viz.web.hub import Hub
from posed.viz.web.server import WebServer
from tests.viz.browser import Browser

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
ROBOT = "webview"


def _daemon(tmp_path: Path, source: str, *settings: str):
    endpoint = free_endpoint()
    state = tmp_path / "state"
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={state}", f'zenoh.listen=["{endpoint}"]',
                       "zenoh.event_republish_s=2", "logging.format=json", *settings], source=source)
    log = open(tmp_path / "daemon.log", "w")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
    return proc, endpoint, state, log


def _web(endpoint: str):
    proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "web", ROBOT, "--connect", endpoint, "--port", "0",
                             "--wait", "180"],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = proc.stdout.readline().strip()
    assert url.startswith("http://127.0.0.1:"), proc.stderr.read() if proc.poll() is not None else url
    return proc, url


@pytest.fixture
def live(tmp_path):
    started = []

    def start(source: str, *settings: str):
        daemon, endpoint, state, log = _daemon(tmp_path, source, *settings)
        started.append((daemon, log))
        web, url = _web(endpoint)
        started.append((web, None))
        browser = Browser(tmp_path / "profile")
        started.append((browser, None))
        browser.open(url)
        return browser, state

    yield start
    for thing, log in reversed(started):
        if isinstance(thing, Browser):
            thing.close()
        else:
            stop(thing, 10.0)
        if log is not None:
            log.close()


@pytest.mark.slow
def test_live_view_shows_the_moving_skeleton_and_the_fps(live, shared_data):
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    b, _ = live(f"file:{video}?loop=true")
    b.wait_for("window.posedView && posedView.poses >= 10", 180, "poses on the page")
    knees, hips_y = [], []
    for _ in range(30):   # 9 s: about two squats (the clip is 13 s of squats at 5 fps)
        v = b.js("[posedView.lastPose.angles.theta_kn_l, posedView.lastPose.joints.left_knee[1], posedView.drawn]")
        if v[0] is not None:
            knees.append(v[0])
        hips_y.append(v[1])
        time.sleep(0.3)
    # the person squats from standing (knee ~0-20 deg) to deep (~100 deg): the drawn skeleton must follow
    assert max(knees) - min(knees) > 40, knees
    assert max(hips_y) - min(hips_y) > 0.03
    fps = b.wait_for("document.getElementById('st-fps').textContent.match(/^[0-9.]+$/) && "
                     "document.getElementById('st-fps').textContent", 30, "the fps in the status")
    assert float(fps) > 0
    assert b.js("posedView.drawn") >= 10
    assert b.js("document.querySelectorAll('img, video, picture, iframe').length") == 0   # never an image
    assert b.js("document.getElementById('angles-now').textContent").count("knee flexion") == 2
    # what the 3D came from: the video gives no intrinsics, the landmark stage keeps BlazePose's world landmarks
    assert b.js("document.getElementById('st-evidence').textContent") == "2D landmarks + BlazePose 3D, assumed lens"
    b.screenshot(ARTIFACTS / "web_live_squat.png")


@pytest.mark.slow
def test_fall_appears_and_the_button_acknowledges_it_in_the_journal(live, shared_data):
    labels = json.loads((shared_data / "falls" / "urfd_dev" / "labels.json").read_text())["camera"]
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    b, state = live(f"file:{rec}", f"falls.camera_height_m={labels['camera_height_m']}",
                    f"falls.camera_tilt_deg={labels['camera_tilt_deg']}",
                    f"falls.camera_roll_deg={labels['camera_roll_deg']}")
    event_id = b.wait_for("document.querySelector('button.ack') && document.querySelector('button.ack')"
                          ".dataset.eventId", 180, "a fall event with its acknowledge button")
    assert "fall" in b.js("document.getElementById('events').textContent")
    assert not b.js("document.getElementById('alarm').hidden")
    b.screenshot(ARTIFACTS / "web_fall.png")
    # as a caregiver would: acknowledge until no button is left (a later state of the fall, e.g. on_floor
    # after falling, is a new message that needs its own acknowledgement)
    clicks, quiet_since, deadline = 0, None, time.monotonic() + 90
    while time.monotonic() < deadline:
        if b.js("!!document.querySelector('button.ack:not([disabled])')"):
            b.js("document.querySelector('button.ack:not([disabled])').click()")
            clicks += 1
            b.wait_for(f"posedView.acked[{json.dumps(event_id)}] === true", 30, "the acknowledgement confirmed")
            quiet_since = None
        elif b.js("!document.querySelector('button.ack')"):
            quiet_since = quiet_since or time.monotonic()
            if time.monotonic() - quiet_since > 4:    # two republish periods without a new message
                break
        time.sleep(0.5)
    assert clicks >= 1 and b.js("document.querySelector('button.ack')") is None
    with EventJournal(state / "events.sqlite3", readonly=True) as journal:
        stored = journal.query()
    assert stored and all(s.acked_at is not None for s in stored), [(s.key, s.acked_at) for s in stored]
    assert {s.event.id for s in stored} == {event_id}
    rows = "[...document.querySelectorAll('#history tr')].slice(1)"
    b.wait_for(f"{rows}.length >= 1 && {rows}.every(tr => tr.lastElementChild.textContent.trim() !== 'no')",
               45, "the event history showing every message acknowledged")
    b.screenshot(ARTIFACTS / "web_fall_acknowledged.png")


# ---------------------------------------------------------------------- the server's doors (no Zenoh needed)
class _NoRobot:
    """The robot side is never reached by these requests: each is refused before it."""

    def ack(self, event_id, by=None):
        raise AssertionError("a refused request reached the robot")

    def history(self, since=None, until=None):
        return []


def _request(port, method, path, host="127.0.0.1", headers=None, body=None):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request(method, path, body=body, headers={"Host": f"{host}:{port}", **(headers or {})})
    r = conn.getresponse()
    data = r.read()
    conn.close()
    return r.status, data


@pytest.fixture
def server():
    servers = []

    def start(token=""):
        import threading

        s = WebServer(Hub("r"), _NoRobot(), "127.0.0.1", 0, token)
        threading.Thread(target=s.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        servers.append(s)
        return s.server_address[1]

    yield start
    for s in servers:
        s.shutdown()
        s.server_close()


def test_server_refuses_foreign_hosts_and_unmarked_acks(server):
    port = server()
    assert _request(port, "GET", "/")[0] == 200
    assert _request(port, "GET", "/", host="attacker.example")[0] == 403          # DNS rebinding
    status, _ = _request(port, "POST", "/api/ack", body=b'{"id": "x"}',
                         headers={"Content-Type": "application/json"})
    assert status == 403                                                            # no X-Posed header
    assert _request(port, "GET", "/static/../server.py")[0] == 404
    assert _request(port, "GET", "/static/app.js")[0] == 200


def test_server_with_a_token_needs_it(server):
    token = "0123456789abcdef0123"
    port = server(token)
    assert _request(port, "GET", "/")[0] == 401
    assert _request(port, "GET", "/?token=wrong-token-wrong-token")[0] == 401
    assert _request(port, "GET", f"/?token={token}")[0] == 200
    assert _request(port, "GET", "/api/history", headers={"Authorization": f"Bearer {token}"})[0] == 200


def test_config_refuses_serving_beyond_localhost_without_a_token():
    from posed.daemon.config import load_config
    from posed.daemon.config.load import ConfigError

    with pytest.raises(ConfigError) as exc:
        load_config(None, overrides=["web.host=0.0.0.0"])
    assert "web" in str(exc.value) and "token" in str(exc.value)
    cfg = load_config(None, overrides=["web.host=0.0.0.0", "web.token=0123456789abcdef"])
    assert cfg.web.token and not load_config(None).web.token
