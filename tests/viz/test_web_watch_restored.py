"""The live view, in a real headless Chromium, through `posed web`, against real daemons (`posed run`) replaying
the real fall of urfd_04 (tests/viz/test_web.py's set-up), shows what landed with the alarm kept across a
restart and raised without frames:

* the recording ends after the fall: the page says posed is NOT WATCHING (a red bar, the badge, the pipeline
  row), never just "live" while no fall can be detected;
* the alarm raised without camera frames says so (``without_frames_s``);
* the acknowledgement carries the name typed on the page: the daemon's journal keeps it (``acked_by``) and
  the page's history shows it;
* the daemon killed (kill -9) while the person lies on the floor and started again: the page shows the fall
  taken back (the status's ``falls.restored_open``: when its alarm is due), then its alarm marked as raised
  after the restart (``restored``).
Screenshots go to build/test-artifacts/."""

from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import pytest

from posed.commands._child import free_endpoint, run_command
from posed.daemon.outbox.journal import EventJournal
from tests.viz.browser import Browser
from tests.viz.web_cli import posed_web

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
ROBOT = "webwatch"
EVENTS = "(document.getElementById('events') || {textContent: ''}).textContent"
HISTORY = "(document.getElementById('history') || {textContent: ''}).textContent"


def _geometry(shared_data: Path) -> list[str]:
    cam = json.loads((shared_data / "falls" / "urfd_dev" / "labels.json").read_text())["camera"]
    return [f"falls.camera_height_m={cam['camera_height_m']}", f"falls.camera_tilt_deg={cam['camera_tilt_deg']}",
            f"falls.camera_roll_deg={cam['camera_roll_deg']}"]


def _daemon(procs, tmp_path, endpoint, source, *settings):
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={tmp_path / 'state'}",
                       f'zenoh.listen=["{endpoint}"]', "zenoh.event_republish_s=2", "logging.format=json",
                       *settings], source=source)
    log = open(tmp_path / f"daemon{len(procs)}.log", "w")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    log.close()
    procs.append(proc)
    return proc


def _page(procs, tmp_path, endpoint) -> Browser:
    web, url = posed_web(ROBOT, endpoint, 180)
    procs.append(web)
    b = Browser(tmp_path / "profile")
    procs.append(b)
    b.open(url)
    return b


@pytest.mark.slow
def test_not_watching_alarm_without_frames_and_who_acknowledged(procs, tmp_path, shared_data):
    endpoint = free_endpoint()
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    _daemon(procs, tmp_path, endpoint, f"file:{rec}", *_geometry(shared_data))
    b = _page(procs, tmp_path, endpoint)        # posed web prints its address once it reaches the daemon
    b.wait_for(f"{EVENTS}.includes('ALARM')", 240, "the alarm on the page")
    # the recording ended seconds after the fall: posed runs, but sees nothing
    assert not b.js("document.getElementById('watching').hidden")
    bar = b.js("document.getElementById('watching').textContent")
    assert "NOT WATCHING" in bar and "a fall would NOT be detected" in bar, bar
    assert b.js("document.getElementById('conn').textContent") == "live, NOT WATCHING"
    assert b.js("document.getElementById('st-watching').textContent").startswith("NO")
    text = b.js(EVENTS)
    assert "raised with no camera frame for" in text and "the person was not seen" in text, text
    b.screenshot(ARTIFACTS / "web_not_watching_alarm_without_frames.png")
    # acknowledged by a named person, kept in the robot's journal and shown
    b.js("document.getElementById('ack-by').value = 'Anna (daughter)'")
    b.js("document.querySelector('button.ack:not([disabled])').click()")
    b.wait_for("document.querySelector('#events .ok') && "
               "document.querySelector('#events .ok').textContent.includes('by Anna (daughter)')", 60,
               "acknowledged by Anna on the page")
    with EventJournal(tmp_path / "state" / "events.sqlite3", readonly=True) as journal:
        stored = journal.query()
    assert stored and {s.acked_by for s in stored} == {"Anna (daughter)"}, [(s.key, s.acked_by) for s in stored]
    b.wait_for(f"{HISTORY}.includes('by Anna (daughter)')", 45, "the history naming who acknowledged")
    assert "raised with no camera frame for" in b.js(HISTORY)


@pytest.mark.slow
def test_a_fall_taken_back_after_a_kill_is_shown(procs, tmp_path, shared_data):
    endpoint = free_endpoint()
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    empty = tmp_path / "nobody.landmarks.jsonl"     # the camera after the restart: nobody in view
    header = rec.read_text().splitlines()[0]
    empty.write_text(header + "\n" + "".join(json.dumps({"seq": i, "t": round(i / 30, 3), "landmarks": None}) + "\n"
                                             for i in range(60)))
    alarm = "falls.alarm_after_s=25"
    first = _daemon(procs, tmp_path, endpoint, f"file:{rec}", *_geometry(shared_data), alarm)
    b = _page(procs, tmp_path, endpoint)
    b.wait_for(f"{EVENTS}.includes('on the floor')", 240, "the fall on the floor on the page")
    os.killpg(first.pid, signal.SIGKILL)         # the daemon dies before the alarm is due
    first.wait()
    _daemon(procs, tmp_path, endpoint, f"file:{empty}", *_geometry(shared_data), alarm)
    b.wait_for("!document.getElementById('st-restored-row').hidden", 120, "the fall taken back, in the status")
    due = b.js(EVENTS)
    assert "ALARM due at" in due and "unless the person is seen up" in due, due
    b.screenshot(ARTIFACTS / "web_fall_taken_back.png")
    b.wait_for(f"{EVENTS}.includes('ALARM') && {EVENTS}.includes('posed restarted during this fall')", 90,
               "the restored alarm marked as raised after the restart")
    b.wait_for(f"{HISTORY}.includes('posed restarted during this fall')", 45, "the history marking it")
    b.screenshot(ARTIFACTS / "web_restored_alarm.png")
