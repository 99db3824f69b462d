"""``posed web '*'`` with several robots (a care home's station, a fleet router): a card per robot — up or gone and
since when, watching or why not, falls not acknowledged, its last pose's time in its own zone, frames per second
— and the skeleton, the angles and the pipeline card of ONE robot: the one with an unacknowledged alarm, else the
first by id, or the one whose card was clicked (kept in the address, so a reload keeps it). Poses of another
robot never reach the skeleton shown.

The first test is the whole chain: a zenoh-python router on 127.0.0.1 (multicast scouting off), robots on it as
real Zenoh publishers (each its liveliness token, a status every 0.3 s, poses at 10 Hz whose left knee is where
no other robot's is, its own time zone), a real ``posed web '*'`` process and a headless Chromium. The others
drive the real hub: bounded with many robots, each page sent its robot's poses only, one robot's page as before.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import threading
import time
from pathlib import Path
from zoneinfo import ZoneInfo

import pytest

from posed.client.types import Status
from posed.falls import FallEvent
from posed.fitting import FitResult
from posed.viz.web.hub import WINDOW_S, Hub
from tests.daemon import zenoh_util
from tests.viz.browser import Browser
from tests.viz.web_cli import posed_web

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
SHOT = Path(os.environ.get("POSED_WEB_CARDS_SHOT", ARTIFACTS / "web_cards.png"))
ZONES = {"r1": "Europe/Berlin", "r2": "America/New_York", "r3": "Asia/Tokyo"}
KNEE_X = {"r1": 0.11, "r2": -0.22, "r3": 0.33}      # each robot's left knee, x (m): whose pose was drawn
KNEE_DEG = {"r1": 30.0, "r2": 80.0, "r3": 55.0}
STATUS_PERIOD_S = 0.3


def _pose(robot: str, seq: int, t_unix: float) -> FitResult:
    return FitResult(seq, seq * 0.1, True, joint_angles_deg={"theta_kn_l": KNEE_DEG[robot]},
                     joints_3d={"mid_hip": (0.0, 0.0, 0.0), "left_hip": (0.1, 0.0, 0.0),
                                "left_knee": (KNEE_X[robot], 0.45, 0.0), "right_hip": (-0.1, 0.0, 0.0)},
                     extra={"time_unix": t_unix})


def _status(robot: str, watching: bool = True) -> dict:
    now = time.time()
    watch = {"watching": True, "since_unix": now - 60} if watching else \
        {"watching": False, "since_unix": now - 3600, "reason": "camera ended", "detail": ""}
    return {"format": "posed.status", "robot": robot, "state": "running", "time_unix": now, "fps": 10.0,
            "drops": 0, "restarts": 0, "latency_ms": {"p95": 20.0},
            "camera": {"state": "open" if watching else "ended"}, "events": {"unacknowledged": 0},
            "time_zone": ZONES[robot], "watch": watch}


class FakeRobot:
    """A robot on the bus: a Zenoh client session of its own to the router, its liveliness token, a status every
    ``STATUS_PERIOD_S`` and a pose every 0.1 s until ``silence()`` (the token stays) or ``stop()`` (gone)."""

    def __init__(self, robot: str, endpoint: str, watching: bool = True) -> None:
        self.robot, self.watching = robot, watching
        self.session = zenoh_util.client(endpoint)
        self.token = self.session.liveliness().declare_token(f"posed/{robot}/alive")
        self._quiet = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        seq, next_status = 0, 0.0
        while not self._quiet.wait(0.1):
            seq += 1
            self.session.put(f"posed/{self.robot}/pose", json.dumps(_pose(self.robot, seq, time.time()).to_json()))
            if time.monotonic() >= next_status:
                next_status = time.monotonic() + STATUS_PERIOD_S
                self.session.put(f"posed/{self.robot}/status", json.dumps(_status(self.robot, self.watching)))

    def alarm(self, event_id: str) -> float:
        """The three messages of a fall whose alarm is raised (nobody acknowledges); returns its wall time."""
        now = dt.datetime.now(dt.UTC)
        wall = now.isoformat(timespec="milliseconds").replace("+00:00", "Z")
        for state in ("falling", "on_floor", "alarm"):
            ev = FallEvent(event_id, self.robot, state, 1.0, 1.5, 2.0, 0.9, wall_time=wall)
            self.session.put(f"posed/{self.robot}/events/fall", json.dumps(ev.to_json()))
        return now.timestamp()

    def silence(self) -> None:
        self._quiet.set()
        self._thread.join(5)

    def stop(self) -> None:
        self.silence()
        if self.session is not None:
            self.token.undeclare()
            self.session.close()
            self.session = None


def _card(b: Browser, robot: str) -> str:
    return b.js(f"(document.querySelector('.robot-card[data-robot=\"{robot}\"]') || {{}}).textContent || ''")


def _drawn_only(b: Browser, robot: str, seconds: float = 2.0) -> None:
    """For ``seconds``: the skeleton shown is ``robot``'s pose (its left knee), the pipeline card its status, and
    no other robot's pose was drawn since it was chosen."""
    b.wait_for(f"posedView.lastPose && posedView.lastPose.joints.left_knee[0] === {KNEE_X[robot]} && "
               "Object.keys(posedView.poseRobots).length", 20, f"{robot}'s skeleton")
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        got = b.js("({x: posedView.lastPose.joints.left_knee[0], good: posedView.lastGood.joints.left_knee[0], "
                   "from: Object.keys(posedView.poseRobots), status: posedView.status && posedView.status.robot, "
                   "knee: document.getElementById('angles-now').textContent})")
        assert got["x"] == KNEE_X[robot] and got["good"] == KNEE_X[robot], got
        assert f"{round(KNEE_DEG[robot])}°" in got["knee"], got
        assert got["from"] == [robot] and got["status"] == robot, got
        time.sleep(0.2)
    assert b.js("posedView.poses") >= 5


def _robot_time(t_unix: float, robot: str) -> str:
    return dt.datetime.fromtimestamp(t_unix, ZoneInfo(ZONES[robot])).strftime("%H:%M:%S")


@pytest.mark.timeout(240)
def test_a_station_shows_a_card_per_robot_and_follows_one(tmp_path, procs):
    rep = f"tcp/127.0.0.1:{zenoh_util.free_port()}"
    router = zenoh_util.router(rep)
    robots = {"r2": FakeRobot("r2", rep, watching=False), "r1": FakeRobot("r1", rep)}
    try:
        proc, url = posed_web("*", rep, 60)
        procs.append(proc)
        b = Browser(tmp_path / "profile")
        procs.append(b)
        b.open(url)
        b.wait_for("Object.keys(posedView.cards).sort().join() === 'r1,r2' && "
                   "Object.values(posedView.cards).every(c => c.state === 'up' && c.pose_unix && c.fps)", 60,
                   "both robots' cards, up")
        assert b.js("document.getElementById('robots').hidden") is False
        r1, r2 = _card(b, "r1"), _card(b, "r2")
        assert "watching" in r1 and "NOT WATCHING" not in r1 and "(Europe/Berlin)" in r1 and "10.0 fps" in r1, r1
        assert "NOT WATCHING: the camera stopped (the recording ended)" in r2 and "(America/New_York)" in r2, r2
        assert "no fall event open" in r1 and "no fall event open" in r2
        # its last pose's time, on its clock, in its zone (read together: it changes every second)
        card, pose_at = b.js("[document.querySelector('.robot-card[data-robot=\"r2\"]').textContent, "
                             "posedView.cards.r2.pose_unix]")
        assert abs(pose_at - time.time()) < 10 and f"last pose {_robot_time(pose_at, 'r2')}" in card, card
        # no alarm anywhere: the first robot by id; its poses only, its status only
        assert b.js("[posedView.selected, posedView.selectedBy]") == ["r1", "default"]
        _drawn_only(b, "r1")
        assert b.js("document.getElementById('robot').textContent") == "every robot (skeleton and pipeline: r1)"
        assert b.js("document.querySelector('.robot-card.selected').dataset.robot") == "r1"
        # r2 raises an alarm nobody acknowledged: the page follows r2 (its card counts it)
        fell_at = robots["r2"].alarm("e" * 32)
        b.wait_for("posedView.selected === 'r2'", 20, "the robot with the alarm followed")
        _drawn_only(b, "r2")
        assert "1 fall event(s) not acknowledged" in _card(b, "r2") and "no fall event open" in _card(b, "r1")
        # the carer clicks r1's card: followed whatever the alarm, in the address, and after a reload
        b.js("document.querySelector('.robot-card[data-robot=\"r1\"]').click()")
        b.wait_for("posedView.selected === 'r1' && posedView.selectedBy === 'hash'", 20, "r1 followed on a click")
        assert b.js("location.hash") == "#robot=r1"
        _drawn_only(b, "r1")
        # r2's fall in the list: at its time in r2's zone, named (the page's times are r1's now)
        entry = b.wait_for("(document.querySelector('#events li[data-event-id]') || {}).textContent", 10, "the fall")
        day = dt.datetime.fromtimestamp(fell_at, ZoneInfo(ZONES["r2"])).strftime("%Y-%m-%d")
        assert f"{day} {_robot_time(fell_at, 'r2')} (America/New_York) · robot r2 · eeeeeeee" in entry, entry
        b.js("window.beforeReload = true; location.reload()")
        b.wait_for("!window.beforeReload && document.readyState === 'complete' && posedView.cards.r1 && "
                   "posedView.lastPose && posedView.poses > 3", 30, "the page again, after the reload")
        assert b.js("[posedView.selected, posedView.selectedBy, location.hash]") == ["r1", "hash", "#robot=r1"]
        _drawn_only(b, "r1")
        # a robot new on the bus appears
        robots["r3"] = FakeRobot("r3", rep)
        b.wait_for("posedView.cards.r3 && posedView.cards.r3.state === 'up'", 30, "r3's card")
        assert "(Asia/Tokyo)" in _card(b, "r3")
        # r3 goes silent (its token stays): gone, since when in its zone
        robots["r3"].silence()
        b.wait_for("posedView.cards.r3.state === 'down' && posedView.cards.r3.why === 'silent'", 30, "r3 silent")
        r3 = _card(b, "r3")
        assert f"GONE since {_robot_time(b.js('posedView.cards.r3.since_unix'), 'r3')}" in r3, r3
        assert "sends nothing" in r3
        b.js("window.scrollTo(0, 0)")
        b.screenshot(SHOT)
        # r2 stops (its liveliness token goes): gone, since when in its zone, still listed with its open fall
        robots["r2"].stop()
        b.wait_for("posedView.cards.r2.state === 'down' && posedView.cards.r2.why === 'gone'", 30, "r2 gone")
        since = b.js("posedView.cards.r2.since_unix")
        r2 = _card(b, "r2")
        assert f"GONE since {_robot_time(since, 'r2')}" in r2 and "falls NOT detected" in r2, r2
        assert "1 fall event(s) not acknowledged" in r2
        assert b.js("[posedView.cards.r1.state, Object.keys(posedView.cards).sort().join()]") == ["up", "r1,r2,r3"]
        _drawn_only(b, "r1", 1.0)
    finally:
        for r in robots.values():
            r.stop()
        router.close()


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def _drain(q) -> list[dict]:
    out = []
    while not q.empty():
        out.append(q.get())
    return out


def _status_of(robot: str) -> Status:
    return Status.from_json(_status("r1") | {"robot": robot}, robot)


def test_many_robots_are_bounded_and_each_page_gets_its_robots_poses_only():
    clock = _Clock()
    hub = Hub("*", pose_rate_hz=1000.0, clock=clock, monotonic=clock, wall=clock, max_robots=50)
    r7, r8, nobody = hub.subscribe("r7"), hub.subscribe("r8"), hub.subscribe()
    robots = [f"r{i}" for i in range(120)]
    for k in range(2):                              # two rounds: a status and 100 poses each, per robot
        for robot in robots:
            clock.now += 0.001
            hub.on_alive(True, robot)
            hub.on_status(robot, _status_of(robot))
            for i in range(100):
                clock.now += 0.0011
                hub.on_pose(robot, _pose("r1", k * 1000 + i, clock.now))
    snap = hub.snapshot("r7")
    assert len(snap["cards"]) == 50 and snap["unlisted"] == 70 and snap["max_robots"] == 50
    spans = [x.angles[-1][0] - x.angles[0][0] for x in hub._robots.values()]
    assert len(hub._robots) == 50 and max(spans) <= WINDOW_S
    # the pages: r7's poses to r7's, r8's to r8's, none to a page with none chosen (all robots were unlisted or
    # the queue's 256 newest: newest wins)
    got7, got8 = _drain(r7), _drain(r8)
    assert {m.get("robot") for m in got7 if m["type"] in ("pose", "status", "alive")} == {"r7"}
    assert {m.get("robot") for m in got8 if m["type"] in ("pose", "status", "alive")} == {"r8"}
    assert not [m for m in _drain(nobody) if m["type"] in ("pose", "status", "alive")]
    assert snap["shown_robot"] == "r7" and snap["status"]["robot"] == "r7" and snap["pose"]["robot"] == "r7"
    # one cards message a tick, whatever the number of robots; none when nothing changed
    hub.tick()
    msgs = [m for m in _drain(r7) if m["type"] == "cards"]
    assert len(msgs) == 1 and len(msgs[0]["cards"]) == 50
    _drain(r8)
    hub.tick()
    assert not [m for m in _drain(r7) + _drain(r8) if m["type"] == "cards"]
    # a robot that goes is kept, gone; with no other event the default robot is the first by id
    hub.on_alive(False, "r0")
    hub.tick()
    (cards,) = [m for m in _drain(r8) if m["type"] == "cards"]
    assert [(c["robot"], c["state"], c["why"]) for c in cards["cards"]] == [("r0", "down", "gone")]
    assert hub.default_robot() == "r0"
    # a robot's alarm not acknowledged makes it the default
    ev = FallEvent("f1", "r9", "alarm", 1.0, 1.5, 2.0, 0.9, wall_time="2026-12-07T10:00:00Z")
    hub.on_event("r9", ev)
    assert hub.default_robot() == "r9"
    hub.on_acked("f1", True)
    assert hub.default_robot() == "r0"
    # a robot gone for more than a week makes room for a new one (said: forget)
    clock.now += 8 * 86400
    hub.on_status("new", _status_of("new"))
    hub.tick()
    (cards,) = [m for m in _drain(r8) if m["type"] == "cards"]
    assert cards["forget"] and "new" in {c["robot"] for c in cards["cards"]}
    assert len(hub._robots) == 50


def test_one_robots_page_has_no_cards(served_page):
    """``posed web ROBOT`` and the daemon's page: no card strip; everything of the robot as before."""

    class _Link:
        def history(self):
            return []

    hub = Hub("r1")
    hub.on_status("r1", _status_of("r1"))
    hub.on_pose("r1", _pose("r1", 1, time.time()))
    b = served_page(hub, _Link(), "window.posedView && posedView.lastPose && posedView.status")
    assert b.js("[posedView.everyRobot, document.getElementById('robots').hidden, posedView.selected]") == \
        [False, True, None]
    assert b.js("posedView.lastPose.joints.left_knee[0]") == KNEE_X["r1"]
    assert b.js("document.getElementById('robot').textContent") == "r1"
    assert hub.snapshot()["cards"] is None
