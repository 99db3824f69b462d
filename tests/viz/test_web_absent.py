"""The live view and the absence notice: a robot on a real Zenoh router on 127.0.0.1 publishing its status every
0.3 s with ``presence`` as the daemon does (tests/viz/absent_robot.py), a real ``posed web`` process, a real
headless Chromium. While the notice runs the pipeline card's "person" row says, in red, "not seen for 3 h 10 min
— longer than on any of the last 14 days (usually back within 2 h 5 min)", with a red bar "home: person not seen
for ..." (and on ``posed web '*'`` the robot's card the same); seen again, "in view" and no bar; seen 12 min ago,
"last seen HH:MM (12 min ago)" in the robot's zone. Screenshot: POSED_WEB_ABSENT_SHOT (default
build/test-artifacts/web_absent.png; docs/img/web-absent.png is one)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.viz.absent_robot import MIN, SHOWN, AbsentRobot
from tests.viz.browser import Browser
from tests.viz.paused_robot import hhmm
from tests.viz.web_cli import posed_web, web_page

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
SHOT = Path(os.environ.get("POSED_WEB_ABSENT_SHOT", ARTIFACTS / "web_absent.png"))
RED = "rgb(183, 28, 28)"        # .warn's colour (style.css)


def person(b: Browser) -> str:
    return b.js("(r => r.hidden ? '' : document.getElementById('st-person').textContent)"
                "(document.getElementById('st-person-row'))")


@pytest.mark.timeout(240)
def test_the_page_says_when_the_person_was_last_seen_and_in_red_when_not_for_longer_than_usual(tmp_path, procs, bus):
    endpoint, robots = bus
    zone = "Asia/Tokyo"                  # not this machine's (UTC): the page's times are the robot's
    robot = AbsentRobot("home", endpoint, zone, "absent")     # absent from the start: no body was ever seen
    robots.append(robot)
    b = web_page("home", endpoint, procs, tmp_path / "profile")
    b.wait_for("posedView.status && posedView.live && posedView.status.presence", 60, "a live status")
    assert person(b) == SHOWN
    assert b.js("getComputedStyle(document.getElementById('st-person')).color") == RED
    assert b.shown("absent") == f"home: person {SHOWN}"
    assert b.js("getComputedStyle(document.getElementById('absent')).backgroundColor") == "rgb(198, 40, 40)"
    assert b.shown("watching") == "" and b.shown("down") == ""     # posed watches: only the person is missing
    b.wait_for("posedView.poses > 0", 10, "a pose (no person)")
    b.js("window.scrollTo(0, 0)")
    b.screenshot(SHOT)

    every, every_url = posed_web("*", endpoint, 60)          # the station: the robot's card says it too
    procs.append(every)
    c = Browser(tmp_path / "profile2")
    procs.append(c)
    c.open(every_url)
    card = c.wait_for("(e => e && e.textContent)(document.querySelector('.robot-card .rc-person'))", 60,
                      "the card's person line")
    assert card == f"person {SHOWN}"
    assert c.js("getComputedStyle(document.querySelector('.robot-card .rc-person')).color") == RED

    robot.presence = "back"
    b.wait_for("posedView.status.presence && !posedView.status.presence.absent", 20, "seen again")
    assert person(b) == "in view"
    assert b.js("getComputedStyle(document.getElementById('st-person')).color") != RED
    assert b.shown("absent") == ""
    c.wait_for("document.querySelector('.robot-card .rc-person').textContent === 'person in view'", 20,
               "the card seen again")

    robot.presence = "seen"                                  # seen 12 min ago: when, in the robot's zone
    want = f"last seen {hhmm(robot.t0 - 12 * MIN, zone)} (12 min ago)"
    b.wait_for(f"document.getElementById('st-person').textContent === {want!r}", 20, want)
    assert b.js("getComputedStyle(document.getElementById('st-person')).color") != RED
    assert b.shown("absent") == ""
