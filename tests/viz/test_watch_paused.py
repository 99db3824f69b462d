"""``posed watch`` of a robot paused for privacy: a real ``posed watch`` process reading a robot on a real Zenoh
router on 127.0.0.1 (tests/viz/paused_robot.py: its status as the daemon publishes it while paused). Its line
says "PAUSED for privacy by voice until HH:MM ZONE" (dated when not today), the end in the robot's zone, and not "NOT WATCHING" (a pause
someone asked for is not a fault); a robot that watches says neither."""

from __future__ import annotations

import datetime as dt
import subprocess
import sys
from pathlib import Path
from zoneinfo import ZoneInfo

import pytest

from posed.commands.watch import paused_words
from tests.viz.paused_robot import Robot, hhmm

ROOT = Path(__file__).resolve().parents[2]


def watch(robot: str, endpoint: str, seconds: float = 4.0) -> list[str]:
    r = subprocess.run([sys.executable, "-m", "posed.cli", "watch", robot, "--connect", endpoint, "--seconds",
                        str(seconds)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.splitlines()


@pytest.mark.timeout(180)
def test_watch_says_a_robot_is_paused_by_whom_until_when(bus):
    endpoint, robots = bus
    zone = "Asia/Tokyo"                      # not this machine's zone: the end is the robot's clock
    paused, watching = Robot("home", endpoint, zone), Robot("other", endpoint, "Europe/Berlin")
    robots += [paused, watching]
    until = paused.pause("voice", 30)
    end = f"{hhmm(until, zone)} {dt.datetime.fromtimestamp(until, ZoneInfo(zone)).tzname()}"   # dated past midnight
    lines = [ln for ln in watch("home", endpoint) if "[paused" in ln]
    assert lines, "no line with the paused status"
    assert all(ln.endswith(f"PAUSED for privacy by voice until {end}") for ln in lines), lines
    assert not any("NOT WATCHING" in ln for ln in lines), lines
    every = watch("*", endpoint)
    assert any(ln.startswith("home  ") and f"PAUSED for privacy by voice until {end}" in ln for ln in every), every
    assert not any(ln.startswith("other  ") and ("PAUSED" in ln or "NOT WATCHING" in ln) for ln in every), every
    paused.resume()
    later = watch("home", endpoint, 3.0)
    assert not any("PAUSED" in ln for ln in later) and any("[running" in ln for ln in later), later


def test_the_words_follow_the_status():
    status = {"state": "paused", "time_zone": "Europe/Berlin",
              "privacy": {"paused": True, "by": None, "until_unix": 1_765_000_000.0}}
    # 1_765_000_000 is 2025-12-06 06:46 in Berlin: not today, so dated
    assert paused_words(status) == "PAUSED for privacy until 2025-12-06 06:46 CET"
    assert paused_words(dict(status, state="stopping")).startswith("PAUSED for privacy")   # stopping, still paused
    assert paused_words(dict(status, state="degraded")) is None       # a fault during a pause is said as the fault
    assert paused_words({"state": "running", "privacy": {"paused": False}}) is None
    assert paused_words(None) is None
