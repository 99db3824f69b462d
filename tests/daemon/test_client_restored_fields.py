"""The client on real daemons (`posed run` replaying the real fall of urfd_04): a subscriber gets the fields
that came with the alarm kept across a restart typed, and the JSON Schemas accept the messages as published:

* the alarm raised after the recording ended: ``client.without_frames_s(event)``;
* the daemon killed (kill -9) with the person on the floor and started again: the status's
  ``falls.restored_open`` as ``Status.restored_open`` (``RestoredFall``), the alarm's ``client.restored(event)``;
  while the camera is ended ``Status.not_watching`` says so;
* every message received validates against client/schemas, and the status schema describes
  ``restored_open`` (a malformed one is refused)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
from pathlib import Path

import pytest

from posed.client import PosedClient, RestoredFall, contract, restored, without_frames_s
from posed.commands._child import free_endpoint, run_command, stop
from tests.daemon.bus_seen import Seen

ROOT = Path(__file__).resolve().parents[2]
ROBOT = "clientnew"


def _daemon(tmp_path, endpoint, source, *settings):
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={tmp_path / 'state'}", f'zenoh.listen=["{endpoint}"]',
                       "zenoh.event_republish_s=2", "logging.format=json", "falls.camera_height_m=0.85",
                       "falls.camera_tilt_deg=0", "falls.camera_roll_deg=0", *settings], source=source)
    tmp_path.mkdir(parents=True, exist_ok=True)
    log = open(tmp_path / "daemon.log", "a")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    log.close()
    return proc


@pytest.fixture
def daemons():
    procs: list = []
    yield procs
    for p in procs:
        if p.poll() is None:
            stop(p, 10.0)


def _nobody(tmp_path, rec) -> Path:
    empty = tmp_path / "nobody.landmarks.jsonl"
    empty.write_text(rec.read_text().splitlines()[0] + "\n" + "".join(
        json.dumps({"seq": i, "t": round(i / 30, 3), "landmarks": None}) + "\n" for i in range(60)))
    return empty


@pytest.mark.slow
def test_a_subscriber_gets_the_new_fields_typed_and_the_schemas_accept_them(daemons, tmp_path, shared_data):
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    endpoint = free_endpoint()
    daemons.append(_daemon(tmp_path / "a", endpoint, f"file:{rec}"))
    seen = Seen()
    with PosedClient.connect(endpoint, wait_s=180) as c:
        c.on_event(ROBOT, seen.event)
        c.on_status(ROBOT, seen.status)
        alarm = seen.wait(lambda s: next((e for e in s.events if e.state == "alarm"), None), 240)
        assert without_frames_s(alarm) is not None and without_frames_s(alarm) > 0, alarm.extra
        assert restored(alarm) is None
        ended = seen.wait(lambda s: next((st for st in s.statuses if st.not_watching), None), 30)
        assert ended.not_watching == "camera ended"
        for e in seen.events:
            contract.validate(e.to_json(), "fall_event")
        for st in seen.statuses:
            contract.validate(st.raw, "status")
    stop(daemons.pop(), 10.0)

    endpoint = free_endpoint()
    first = _daemon(tmp_path / "b", endpoint, f"file:{rec}", "falls.alarm_after_s=20")
    daemons.append(first)
    seen = Seen()
    with PosedClient.connect(endpoint, wait_s=180) as c:
        c.on_event(ROBOT, seen.event)
        c.on_status(ROBOT, seen.status)
        on_floor = seen.wait(lambda s: next((e for e in s.events if e.state == "on_floor"), None), 240)
        os.killpg(first.pid, signal.SIGKILL)
        first.wait()
        daemons.append(_daemon(tmp_path / "b", endpoint, f"file:{_nobody(tmp_path, rec)}", "falls.alarm_after_s=20"))
        st = seen.wait(lambda s: next((st for st in s.statuses if st.restored_open), None), 120)
        assert st.restored_open[0] == RestoredFall(on_floor.id, st.restored_open[0].due_unix, False, False)
        assert abs(st.restored_open[0].due_unix - (on_floor.extra["t_impact_unix"] + 20)) < 0.5
        alarm = seen.wait(lambda s: next((e for e in s.events if e.state == "alarm"), None), 60)
        r = restored(alarm)
        assert r is not None and r.last_state == "on_floor" and r.due_unix == st.restored_open[0].due_unix
        for e in seen.events:
            contract.validate(e.to_json(), "fall_event")
        for s in seen.statuses:
            contract.validate(s.raw, "status")
        bad = json.loads(json.dumps(st.raw))
        bad["falls"]["restored_open"] = [{"id": 3, "due_unix": "soon"}]
        assert contract.errors(bad, "status"), "the status schema accepts any restored_open"


@pytest.mark.slow
def test_posed_watch_says_not_watching_and_the_frameless_alarm(daemons, tmp_path, shared_data):
    """`posed watch` (built on the client) on a real daemon whose recording ended after the fall: the alarm's
    line says it was raised with no camera frame, the status line that posed is NOT WATCHING."""
    import sys

    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    endpoint = free_endpoint()
    daemons.append(_daemon(tmp_path, endpoint, f"file:{rec}"))
    with PosedClient.connect(endpoint, wait_s=180) as c:           # up: watch from the start of the replay
        seen = Seen()
        c.on_status(ROBOT, seen.status)
        seen.wait(lambda s: s.statuses, 180)
    r = subprocess.run([sys.executable, "-m", "posed.cli", "watch", ROBOT, "--connect", endpoint, "--seconds", "30"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    alarm = [line for line in r.stdout.splitlines() if "FALL alarm" in line]
    assert alarm and alarm[0].endswith("s]") and "[raised with no camera frame for" in alarm[0], r.stdout
    assert any("NOT WATCHING (camera ended): a fall would not be detected" in line
               for line in r.stdout.splitlines()), r.stdout
