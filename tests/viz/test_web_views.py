"""The live page's views, in a real headless Chromium, fed by a real Hub (no robot needed): the fall list newest
first, one entry per event, capped with the rest counted and one click away; the event history one row per
event, newest first, capped; times in ISO 8601 in the browser's zone; the floor from the fall detector's
geometry (the skeleton stands on it, or lies on it); a joint the frame did not measure is not drawn; no model
symbol anywhere on the page, before or after the first pose."""

from __future__ import annotations

import datetime as dt
import math
import os
import re
from pathlib import Path

import pytest

from posed.client.types import Status
from posed.falls import FallEvent
from posed.fitting import BODY_LANDMARK_NAMES, FitResult, Measured
from posed.viz.web.hub import Hub, floor_of

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
T0 = dt.datetime(2026, 12, 2, 18, 0, tzinfo=dt.UTC)
N_EVENTS = 40


def _iso(t: dt.datetime) -> str:
    return t.isoformat(timespec="milliseconds").replace("+00:00", "Z")


class _Robot:
    """The robot's side as the page reaches it: its stored messages (oldest first, as the journal answers)."""

    def __init__(self, messages):
        self.messages = messages

    def ack(self, event_id, by=None):
        raise AssertionError("no acknowledgement in this test")

    def history(self, since=None, until=None):
        return self.messages


def _status(tilt=20.0, floor=1.2):
    raw = {"state": "running", "fps": 30.0, "camera": {"state": "streaming"},
           "falls": {"enabled": True, "geometry": {"tilt_deg": tilt, "roll_deg": 0.0, "floor_below_camera_m": floor,
                                                   "tilt_from": "config", "height_from": "config"}}}
    return Status.from_json(raw, "r")


def _lying_pose(down, floor):
    """A person lying on the floor 3 m in front of a camera tilted down, in camera axes; the left elbow not
    measured (its joint and the wrist's bone must not be drawn)."""
    import numpy as np

    g = np.array(down)
    fwd = np.array([0.0, -g[2], g[1]])            # level, away from the camera (perpendicular to g, x = 0)
    right = np.array([1.0, 0.0, 0.0])
    root = fwd * 3.0 + g * (floor - 0.12)        # mid-hip 12 cm above the floor
    along = {"mid_hip": 0.0, "left_hip": 0.0, "right_hip": 0.0, "left_shoulder": 0.5, "right_shoulder": 0.5,
             "left_elbow": 0.75, "right_elbow": 0.75, "left_wrist": 1.0, "right_wrist": 1.0, "left_knee": -0.45,
             "right_knee": -0.45, "left_ankle": -0.9, "right_ankle": -0.9}
    side = {n: (0.15 if n.startswith("left") else -0.15 if n.startswith("right") else 0.0) for n in along}
    joints = {n: tuple(float(v) for v in right * side[n] + fwd * along[n]) for n in along}
    seen = set(BODY_LANDMARK_NAMES) - {"left_elbow"}
    return FitResult(5, 1.0, True, joint_angles_deg={"theta_kn_l": 4.0, "theta_el_l": 90.0}, joints_3d=joints,
                     extra={"root_cam_m": [float(v) for v in root], "time_unix": T0.timestamp() + 3600},
                     measured=Measured.from_landmarks(seen)), root


@pytest.fixture
def page(served_page):
    return lambda hub, robot: served_page(hub, robot, "window.posedView && document.getElementById('robot')"
                                                      ".textContent === 'r'")


def test_falls_newest_first_grouped_capped_in_iso_local_time(page):
    hub = Hub("r", clock=iter(range(10**6)).__next__)
    messages = []
    for i in range(N_EVENTS):               # a looping replay: the same fall again and again, 2 messages each
        at = T0 + dt.timedelta(minutes=3 * i)
        for k, state in enumerate(("falling", "on_floor")):
            ev = FallEvent(f"ev{i:02d}" + "x" * 6, "r", state, 1.0, 1.5, 2.0 + k + 100 * i, 0.9,
                           wall_time=_iso(at + dt.timedelta(seconds=k)))
            hub.on_event("r", ev)
            messages.append({"id": ev.id, "state": state, "wall_time": ev.wall_time, "confidence": 0.9,
                             "published_at": (at + dt.timedelta(seconds=k)).timestamp(),
                             "acked_at": (at + dt.timedelta(minutes=1)).timestamp() if i < 30 else None})
    for i in range(30):
        hub.on_acked(f"ev{i:02d}xxxxxx", True)
    b = page(hub, _Robot(messages))
    b.wait_for("document.querySelectorAll('#history tr').length > 1", 30, "the event history")
    # the fall list: the newest event first, one entry per event (its messages joined), at most 6 shown
    items = b.js("[...document.querySelectorAll('#events li[data-event-id]')].map(li => li.dataset.eventId)")
    assert items == [f"ev{i:02d}xxxxxx" for i in range(N_EVENTS - 1, N_EVENTS - 7, -1)]
    first = b.js("document.querySelector('#events li').textContent")
    assert "fall → on the floor" in first
    more = b.js("document.querySelector('#events li.more').textContent")
    assert f"{N_EVENTS - 6} earlier event(s), 4 not acknowledged" in more   # 10 open, 6 of them shown
    assert b.js("document.getElementById('alarm').textContent") == "10 fall event(s) not acknowledged"
    b.js("document.querySelector('#events li.more button').click()")
    assert b.js("document.querySelectorAll('#events li[data-event-id]').length") == N_EVENTS
    # the history: one row per event, newest first, capped at 15, the rest counted
    rows = b.js("[...document.querySelectorAll('#history tr')].slice(1).map(tr => [...tr.cells].map(c => "
                "c.textContent.trim()))")
    assert len(rows) == 15
    times = [r[0] for r in rows]
    assert all(re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", t) for t in times), times
    assert times == sorted(times, reverse=True)
    assert rows[0][1] == f"ev{N_EVENTS - 1:02d}xxxx" and rows[0][2] == "fall → on the floor" and rows[0][3] == "no"
    zone = b.js("Intl.DateTimeFormat().resolvedOptions().timeZone")
    local = T0.astimezone(dt.datetime.now().astimezone().tzinfo) if zone in ("UTC", "Etc/UTC") else None
    if local is not None:   # this machine's browser runs in UTC: the times are checkable to the second
        want = (T0 + dt.timedelta(minutes=3 * (N_EVENTS - 1))).strftime("%Y-%m-%d %H:%M:%S")
        assert times[0] == want
    assert zone in b.js("document.querySelector('#history th').textContent")
    assert f"{N_EVENTS - 15} earlier event(s)" in b.js("document.getElementById('history-more').textContent")
    b.screenshot(ARTIFACTS / "web_views_falls.png")


def test_times_are_on_the_robots_clock_in_its_zone_whatever_the_browsers(page):
    """A carer abroad: the page shows the time it happened at home (the status's time_zone), as the report and
    `posed events` do, and names that zone; before the status says, the browser's zone."""
    hub = Hub("r")
    at = T0 + dt.timedelta(minutes=7)
    ev = FallEvent("evzone" + "x" * 6, "r", "falling", 1.0, 1.5, 2.0, 0.9, wall_time=_iso(at))
    hub.on_event("r", ev)
    messages = [{"id": ev.id, "state": "falling", "wall_time": ev.wall_time, "confidence": 0.9,
                 "published_at": at.timestamp(), "acked_at": None}]
    b = page(hub, _Robot(messages))
    b.wait_for("document.querySelectorAll('#history tr').length > 1", 30, "the event history")
    browser_zone = b.js("Intl.DateTimeFormat().resolvedOptions().timeZone")
    robot_zone = "Asia/Tokyo" if browser_zone != "Asia/Tokyo" else "America/New_York"
    assert browser_zone in b.js("document.querySelector('#history th').textContent")
    hub.on_status("r", Status.from_json({"state": "running", "fps": 10.0, "camera": {"state": "open"},
                                         "time_zone": robot_zone}, "r"))
    b.wait_for(f"document.querySelector('#history th').textContent.includes({robot_zone!r})", 30,
               "the history in the robot's zone")
    from zoneinfo import ZoneInfo

    local = at.astimezone(ZoneInfo(robot_zone))
    offset = local.strftime("%z")
    assert f"({robot_zone}, UTC{offset[:3]}:{offset[3:]})" in b.js("document.querySelector('#history th').textContent")
    first = b.js("document.querySelector('#history tr:nth-child(2) td').textContent")
    assert first == local.strftime("%Y-%m-%d %H:%M:%S"), (first, local)
    # a zone this browser does not know is not taken: the times stay in the zone the heading names
    hub.on_status("r", Status.from_json({"state": "running", "time_zone": "Not/AZone"}, "r"))
    b.wait_for("posedView.status && posedView.status.time_zone === 'Not/AZone'", 30, "the odd status")
    assert robot_zone in b.js("document.querySelector('#history th').textContent")


def test_floor_from_the_fall_detector_and_only_measured_joints(page):
    hub = Hub("r")
    b = page(hub, _Robot([]))
    # before any pose: plain names only, never a model symbol
    assert b.js("posedView.legend") == ["left hip flexion", "right hip flexion", "left knee flexion",
                                        "right knee flexion", "trunk flexion"]
    assert "theta" not in b.js("document.body.innerText")
    status = _status()
    floor = floor_of(status.raw)
    hub.on_status("r", status)
    pose, root = _lying_pose(floor["down"], 1.2)
    hub.on_pose("r", pose)
    b.wait_for("posedView.drawn >= 1 && posedView.status && posedView.status.floor", 30, "the pose drawn")
    assert b.js("posedView.floorNote").startswith("floor: the fall detector's, 1.20 m below the camera")
    heights = b.js("(() => { const p = worldPoints(posedView.lastPose); return Object.fromEntries("
                   "Object.entries(p).map(([k, v]) => [k, v[1]])); })()")
    # lying on the floor, seen by a camera tilted 20 degrees: every joint 12 cm above the floor
    assert all(abs(h - 0.12) < 1e-6 for h in heights.values()), heights
    assert "left_elbow" not in heights and "left_wrist" in heights       # not measured: not drawn
    assert b.js("document.getElementById('angles-now').textContent").count("not seen") >= 1
    assert "theta" not in b.js("document.body.innerText")
    b.screenshot(ARTIFACTS / "web_views_floor.png")


def test_the_hub_gravity_is_the_fall_detector_formula():
    from posed.falls.features import gravity_from_tilt

    for tilt, roll in ((0.0, 0.0), (20.0, 0.0), (-10.0, 7.5), (35.0, -12.0)):
        got = floor_of(_status(tilt).raw | {"falls": {"geometry": {"tilt_deg": tilt, "roll_deg": roll}}})
        assert got["below_camera_m"] is None
        assert all(math.isclose(a, b, abs_tol=1e-12) for a, b in zip(got["down"], gravity_from_tilt(tilt, roll),
                                                                        strict=True))
    assert floor_of({"state": "running"}) is None
