"""The live view while posed is paused for privacy (posed/ROBOT/privacy/pause): a robot on a real Zenoh router on
127.0.0.1 (multicast scouting off) publishing its liveliness token and a status every 0.3 s as the daemon does —
running, then ``state: paused`` with its ``privacy`` and the daemon's ``watch`` (not watching, reason
``paused``), then running again — read by a real ``posed web`` process in a real headless Chromium.

* one robot's page: while paused, a plain banner "Watching paused for privacy by voice until HH:MM" (the robot's
  zone, as every time on the page), never the red NOT WATCHING alarm, the header pill "live, paused"; gone when
  the status says watching again. Screenshot: POSED_WEB_PAUSED_SHOT (default build/test-artifacts/web_paused.png);
* ``posed web '*'``: the paused robot's card says "paused" and the banner's words in its own zone, is not a
  robot down, and the other robot's card is untouched; watching again, the card says "watching"."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from tests.viz.browser import Browser
from tests.viz.paused_robot import KNEE_DEG, Robot, hhmm
from tests.viz.web_cli import posed_web, web_page

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
SHOT = Path(os.environ.get("POSED_WEB_PAUSED_SHOT", ARTIFACTS / "web_paused.png"))


@pytest.mark.timeout(240)
def test_the_page_says_a_pause_plainly_and_drops_it_when_watching_again(tmp_path, procs, bus):
    endpoint, robots = bus
    zone = "Asia/Tokyo"                  # not this machine's (UTC): the page's times are the robot's
    robot = Robot("home", endpoint, zone)
    robots.append(robot)
    b = web_page("home", endpoint, procs, tmp_path / "profile")
    b.wait_for("posedView.status && posedView.status.state === 'running' && posedView.live", 60, "a live status")
    assert b.shown("paused") == "" and b.shown("watching") == ""
    b.wait_for("posedView.drawn > 0", 20, "a body drawn")          # it watches: the body and its angles now
    assert f"{KNEE_DEG:.0f}°" in b.js("document.getElementById('angles-now').textContent")

    until = robot.pause("voice", 30)
    b.wait_for("posedView.status && posedView.status.state === 'paused'", 20, "the paused status")
    banner = b.wait_for("(e => e.hidden ? '' : e.textContent)(document.getElementById('paused'))", 10, "the banner")
    assert banner == f"Watching paused for privacy by voice until {hhmm(until, zone)}", banner
    assert b.js("getComputedStyle(document.getElementById('paused')).backgroundColor") != \
        b.js("getComputedStyle(document.getElementById('watching')).backgroundColor")     # not the alarm's red
    assert b.shown("watching") == "" and b.shown("down") == ""                           # not an error, not blind
    assert b.js("document.getElementById('conn').textContent") == "live, paused"
    assert "NOT" not in b.js("document.getElementById('st-watching').textContent")
    assert "paused for privacy by voice" in b.js("document.getElementById('st-watching').textContent")
    # the person asked not to be watched: no body (not even the last one from before), no angles, no minute of them
    drawn = b.js("posedView.drawn")
    time.sleep(1.0)
    assert b.js("posedView.drawn") == drawn
    assert b.js("document.getElementById('angles-now').textContent") == ""
    assert b.js("posedView.angleSamples") == 0
    b.js("window.scrollTo(0, 0)")
    b.screenshot(SHOT)

    robot.resume()
    b.wait_for("posedView.status && posedView.status.state === 'running'", 20, "watching again")
    b.wait_for("document.getElementById('paused').hidden", 5, "the banner gone")
    assert b.js("document.getElementById('conn').textContent") == "live"
    assert b.js("document.getElementById('st-watching').textContent") == "yes"


def _card(b: Browser, robot: str) -> dict:
    return b.js(f"(c => c ? {{text: c.textContent, state: c.dataset.state, cls: c.className}} : null)"
                f"(document.querySelector('.robot-card[data-robot=\"{robot}\"]'))")


@pytest.mark.timeout(240)
def test_a_paused_robots_card_says_paused_in_its_zone(tmp_path, procs, bus):
    endpoint, robots = bus
    zones = {"r1": "America/New_York", "r2": "Europe/Berlin"}
    r1, r2 = Robot("r1", endpoint, zones["r1"]), Robot("r2", endpoint, zones["r2"])
    robots += [r1, r2]
    until = r1.pause("Anna", 45)
    proc, url = posed_web("*", endpoint, 60)
    procs.append(proc)
    b = Browser(tmp_path / "profile")
    procs.append(b)
    b.open(url)
    b.wait_for("Object.keys(posedView.cards).sort().join() === 'r1,r2' && "
               "posedView.cards.r1.paused && posedView.cards.r2.watching", 60, "both cards")
    card = b.wait_for("(c => c && c.dataset.state === 'paused' && c.textContent)"
                      "(document.querySelector('.robot-card[data-robot=\"r1\"]'))", 10, "r1's card paused")
    assert f"Watching paused for privacy by Anna until {hhmm(until, zones['r1'])}" in card, card
    assert "NOT WATCHING" not in card and "GONE" not in card
    c1, c2 = _card(b, "r1"), _card(b, "r2")
    assert "down" not in c1["cls"].split() and "paused" in c1["cls"].split(), c1
    assert c2["state"] == "up" and "watching" in c2["text"] and "paus" not in c2["text"], c2
    b.js("window.scrollTo(0, 0)")
    b.screenshot(SHOT.with_name(SHOT.stem + "_cards.png"))

    r1.resume()
    b.wait_for("(c => c && c.dataset.state === 'up')(document.querySelector('.robot-card[data-robot=\"r1\"]'))",
               20, "r1 watching again")
    c1 = _card(b, "r1")
    assert "watching" in c1["text"] and "paus" not in c1["text"], c1
