"""``posed watch`` and the absence notice: a real ``posed watch`` process reading a robot on a real Zenoh router on
127.0.0.1 whose status carries ``presence`` (tests/viz/absent_robot.py). When the notice begins it prints once
"home: PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)",
when it ends once "home: person seen again after 3 h 25 min" — not on every status (a status every 0.3 s)."""

from __future__ import annotations

import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.viz.absent_robot import BEGUN, ENDED, AbsentRobot

ROOT = Path(__file__).resolve().parents[2]


def lines_of(proc: subprocess.Popen) -> queue.Queue:
    out: queue.Queue = queue.Queue()

    def read():
        for line in proc.stdout:
            out.put(line.rstrip("\n"))
        out.put(None)

    threading.Thread(target=read, daemon=True).start()
    return out


def wait_line(lines: queue.Queue, seen: list[str], pred, timeout: float, what: str) -> str:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=max(0.05, deadline - time.monotonic()))
        except queue.Empty:
            break
        if line is None:
            break
        seen.append(line)
        if pred(line):
            return line
    raise AssertionError(f"no line with {what}: {seen}")


@pytest.mark.timeout(180)
@pytest.mark.parametrize("which", ["home", "*"])
def test_watch_says_when_the_absence_notice_begins_and_ends_once_each(bus, procs, which):
    endpoint, robots = bus
    robot = AbsentRobot("home", endpoint, "Europe/Berlin")
    robots.append(robot)
    proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "watch", which, "--connect", endpoint, "--seconds",
                             "60"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    procs.append(proc)
    lines, seen = lines_of(proc), []
    wait_line(lines, seen, lambda ln: "[running" in ln, 90, "a status")
    robot.presence = "absent"
    wait_line(lines, seen, lambda ln: "PERSON NOT SEEN" in ln, 10, "the notice begun")
    wait_line(lines, seen, lambda ln: "[running" in ln, 10, "a status after it")
    wait_line(lines, seen, lambda ln: "[running" in ln, 10, "another status")    # many statuses, one line
    robot.presence = "back"
    wait_line(lines, seen, lambda ln: "seen again" in ln, 10, "the notice ended")
    wait_line(lines, seen, lambda ln: "[running" in ln, 10, "a status after it")
    wait_line(lines, seen, lambda ln: "[running" in ln, 10, "another status")
    assert [ln for ln in seen if "NOT SEEN" in ln] == [f"home: {BEGUN}"], seen
    assert [ln for ln in seen if "seen again" in ln] == [f"home: {ENDED}"], seen
    summary = [ln for ln in seen if "[running" in ln]
    assert all(ln.startswith("home  ") == (which == "*") for ln in summary), summary
