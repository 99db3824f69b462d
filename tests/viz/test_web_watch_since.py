"""Whether posed is watching, said by the daemon itself (the status's ``watch``), with real daemons (`posed run`
replaying the real fall of urfd_04, urfd_dev), a real Zenoh session on 127.0.0.1, the client, and `posed web` in a
real headless Chromium:

* while the replay runs the status says ``watch.watching`` true; killed -9 with the person on the floor and
  started again on a 2 s recording of nobody that then ends, it says not watching, ``camera ended``, with one
  ``since_unix`` that stays put from status to status; the client's ``Status.watch`` and ``not_watching`` read
  it and the status schema describes it;
* the fall taken back from the journal has its alarm raised while no frame has come for seconds: the alarm
  carries ``without_frames_s`` (before: only the detector's own frameless alarm did);
* `posed web` started long after posed stopped watching (a web server restarted, a page opened later) says
  "NOT WATCHING since HH:MM:SS", the daemon's time, no longer "already when this view started".
Screenshot to build/test-artifacts/."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from posed.client import PosedClient, Watch, contract, restored, without_frames_s
from posed.commands._child import free_endpoint, run_command
from tests.daemon import restore_util as ru
from tests.daemon.bus_seen import Seen
from tests.viz.browser import Browser
from tests.viz.web_cli import posed_web

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("POSED_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
ROBOT = "watchsince"
ALARM_S = 25.0


def _daemon(procs, tmp_path, endpoint, source: Path):
    cmd = run_command([f"robot_id={ROBOT}", f"pipeline.state_dir={tmp_path / 'state'}", f'zenoh.listen=["{endpoint}"]',
                       "zenoh.event_republish_s=2", "logging.format=json", f"falls.alarm_after_s={ALARM_S}",
                       *ru.CAMERA], source=f"file:{source}")
    log = open(tmp_path / f"daemon{len(procs)}.log", "w")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    log.close()
    procs.append(proc)
    return proc


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_daemon_says_since_when_it_is_not_watching_and_a_later_page_shows_it(procs, tmp_path, shared_data):
    header, frames = ru.urfd04(shared_data)
    fall = ru.write(tmp_path / "fall.landmarks.jsonl", header,
                    frames + ru.held(frames[-1], frames[-1].t + 1 / 30, 10.0, seq0=len(frames), nobody=True))
    nobody = ru.write(tmp_path / "nobody.landmarks.jsonl", header, ru.held(frames[0], 0.0, 2.0, nobody=True))
    endpoint = free_endpoint()
    first = _daemon(procs, tmp_path, endpoint, fall)
    seen = Seen()
    with PosedClient.connect(endpoint, wait_s=180) as c:
        c.on_event(ROBOT, seen.event)
        c.on_status(ROBOT, seen.status)
        watching = seen.wait(lambda s: next((st for st in s.statuses if st.state == "running"), None), 180,
                             "a running status")
        assert isinstance(watching.watch, Watch) and watching.watch.watching, watching.raw.get("watch")
        assert watching.watch.reason is None and watching.not_watching is None
        assert watching.watch.since_unix <= watching.time_unix + 1e-3      # both on the status's clock
        on_floor = seen.wait(lambda s: next((e for e in s.events if e.state == "on_floor"), None), 120, "on_floor")
        os.killpg(first.pid, signal.SIGKILL)             # long before the alarm is due
        first.wait()
        restarted = time.time()
        _daemon(procs, tmp_path, endpoint, nobody)       # 2 s of nobody, then the recording ends

        alarm = seen.wait(lambda s: next((e for e in s.events if e.state == "alarm"), None), 120, "the alarm")
        assert alarm.id == on_floor.id and restored(alarm) is not None, alarm.extra
        print(f"restored alarm raised without frames for {without_frames_s(alarm)} s")
        assert without_frames_s(alarm) is not None and without_frames_s(alarm) >= 3.0, alarm.extra
        contract.validate(alarm.to_json(), "fall_event")

        seen.wait(lambda s: sum(1 for st in s.statuses if st.time_unix > restarted and st.not_watching) >= 5, 60,
                  "five statuses not watching")
        with seen.lock:
            after = [st for st in seen.statuses if st.time_unix > restarted and st.watch is not None]
        blind = [st for st in after if not st.watch.watching]
        assert blind and all(st.watch.reason == "camera ended" and st.not_watching == "camera ended" for st in blind)
        since = blind[0].watch.since_unix
        assert all(st.watch.since_unix == since for st in blind), [st.watch for st in blind]
        assert restarted < since <= blind[0].time_unix + 1e-3
        for st in after:
            contract.validate(st.raw, "status")
        bad = dict(blind[0].raw, watch={"watching": "no", "since_unix": "then", "reason": 3})
        assert contract.errors(bad, "status"), "the status schema accepts any watch"

        time.sleep(3.0)         # the page opens later: posed has not been watching for a while already
        web, url = posed_web(ROBOT, endpoint, 120)
        procs.append(web)
        b = Browser(tmp_path / "profile")
        procs.append(b)
        b.open(url)
        b.wait_for("!document.getElementById('watching').hidden", 60, "the NOT WATCHING bar")
        bar = b.js("document.getElementById('watching').textContent")
        shown = b.js(f"clockText({since})")          # the daemon's since, in the page's own words
        assert f"NOT WATCHING since {shown}" in bar and "already when this view started" not in bar, bar
        assert "recording ended" in bar and "a fall would NOT be detected" in bar, bar
        assert f"since {shown}" in b.js("document.getElementById('st-watching').textContent")
        b.screenshot(ARTIFACTS / "web_not_watching_since.png")
