"""The live page on a phone (a caregiver opens it there): at 420 px wide nothing is wider than the window, the
cards stack in one column, the pipeline's values stay inside their card and the angle chart is drawn at the
width it is shown at, its legend under the plot. A real headless Chromium, a real hub and server."""

from __future__ import annotations

import os
import threading
from pathlib import Path

from posed.client.types import Status
from posed.fitting import BODY_LANDMARK_NAMES, FitResult, Measured
from posed.viz.web.hub import Hub
from posed.viz.web.server import WebServer
from tests.viz.browser import Browser

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))


class _Robot:
    def ack(self, event_id):
        raise AssertionError("no acknowledgement here")

    def history(self):
        return []


def _pose(seq: int, knee: float) -> FitResult:
    joints = {"left_hip": (0.1, 0.0, 0.0), "right_hip": (-0.1, 0.0, 0.0), "left_shoulder": (0.15, -0.5, 0.0),
              "right_shoulder": (-0.15, -0.5, 0.0), "left_knee": (0.1, 0.45, 0.05), "right_knee": (-0.1, 0.45, 0.05),
              "left_ankle": (0.1, 0.9, 0.0), "right_ankle": (-0.1, 0.9, 0.0)}
    return FitResult(seq, seq * 0.2, True, joint_angles_deg={"theta_kn_l": knee, "theta_kn_r": knee, "theta_tr": 10.0},
                     joints_3d=joints, extra={"time_unix": 1.8e9 + seq * 0.2, "evidence": ["landmarks", "world"],
                                              "lens": "assumed"},
                     measured=Measured.from_landmarks(set(BODY_LANDMARK_NAMES)))


def test_the_page_fits_a_phone(tmp_path):
    hub = Hub("r", pose_rate_hz=1000.0, clock=iter(range(10**6)).__next__)   # no pose rate-limited away
    hub.on_alive(True)
    hub.on_status("r", Status.from_json({"state": "running", "fps": 4.7, "camera": {"state": "open"},
                                         "latency_ms": {"p95": 53.0}, "drops": 0, "restarts": 0}, "r"))
    for i in range(40):
        hub.on_pose("r", _pose(i, 10.0 + 90.0 * (i % 10) / 10))
    server = WebServer(hub, _Robot(), "127.0.0.1", 0)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    try:
        with Browser(tmp_path / "profile", size=(420, 1400)) as b:
            # a headless window is at least 500 px wide: the viewport is set as a phone's
            b.call("Emulation.setDeviceMetricsOverride", width=420, height=1400, deviceScaleFactor=2, mobile=True)
            b.open(server.url)
            b.wait_for("window.posedView && document.getElementById('st-evidence').textContent.includes('lens')", 30,
                       "the status and the last pose")
            inner = b.js("window.innerWidth")
            assert inner <= 420
            # nothing wider than the window: no sideways scrolling
            assert b.js("document.documentElement.scrollWidth") <= inner
            # one column: every card as wide as the others, each below the one before
            boxes = b.js("[...document.querySelectorAll('main > section')].map(s => { const r = "
                         "s.getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; })")
            assert len({round(x[0]) for x in boxes}) == 1 and all(x[2] <= inner for x in boxes), boxes
            assert all(b2[1] >= b1[3] for b1, b2 in zip(boxes, boxes[1:], strict=False)), boxes
            # the pipeline's values inside their card
            card = b.js("document.getElementById('status').closest('section').getBoundingClientRect().right")
            rights = b.js("[...document.querySelectorAll('#status td, #status th')].map(c => "
                          "c.getBoundingClientRect().right)")
            assert max(rights) <= card + 0.5, (rights, card)
            # the chart drawn at its shown width (not a 900-px drawing squeezed), its legend below the plot
            shown, drawn, dpr = b.js("[document.getElementById('chart').clientWidth, "
                                     "document.getElementById('chart').width, window.devicePixelRatio]")
            assert shown <= inner and abs(drawn - shown * dpr) <= 1, (shown, drawn, dpr)
            assert b.js("posedView.legend").count("left knee flexion") == 1
            b.screenshot(ARTIFACTS / "web_phone.png")
    finally:
        server.shutdown()
        server.server_close()
