"""The live page against a robot used for three months: a real ``posed run`` on a real journal of 3,000 falls over
90 days (written by the daemon's own EventJournal: 25 a day, acknowledged by Anna; one alarm of 80 days ago
never acknowledged; and a backlog of 40 recent falls never published, as when the robot's bus was down), a real
``posed web`` and a headless Chromium. The history lists every fall of the last 7 days (not only the newest 200
messages), a burst of event messages costs the page a few history reads (not one each), the old alarm is on
the page and its button acknowledges it in the journal."""

from __future__ import annotations

import json
import subprocess
import time

import pytest

from posed.commands._child import free_endpoint, run_command
from posed.daemon.outbox.journal import EventJournal
from posed.falls import FallEvent
from tests.viz.browser import Browser
from tests.viz.test_web import ROOT
from tests.viz.web_cli import posed_web

DAY = 86400.0
ROWS = "[...document.querySelectorAll('#history tr')].slice(1)"


def _journal(path, now: float) -> dict:
    """3,000 falls over 90 days before ``now`` (3 messages each: got up, or the alarm), published and
    acknowledged a minute later but the alarm of 80 days ago; then 40 falls of the last hour never published
    (nor acknowledged)."""
    clock = {"now": 0.0}
    made = {"week": set(), "backlog": set(), "old_alarm": None}
    with EventJournal(path, clock=lambda: clock["now"]) as j:
        for i in range(3040):
            backlog = i >= 3000
            t0 = now - 3600 + (i - 3000) * 60 if backlog else now - 90 * DAY + (i + 0.5) * 30 * 86400 / 1000
            eid = FallEvent.new_id()
            old_alarm = i == 333
            states = ("falling", "on_floor", "alarm" if old_alarm or i % 3 == 0 else "recovered")
            for k, st in enumerate(states):
                clock["now"] = t0 + 5 * k
                j.append(FallEvent(eid, "longrun", st, 1.0, 1.5, 2.0 + k, 0.9))
                if not backlog:
                    j.mark_published(eid, st)
            if t0 >= now - 7 * DAY + 60:
                made["week"].add(eid)
            if backlog:
                made["backlog"].add(eid)
            elif old_alarm:
                made["old_alarm"] = eid
            else:
                clock["now"] = t0 + 60
                j.acknowledge(eid, by="Anna")
    return made


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_three_months_of_falls_on_the_page(tmp_path, shared_data, procs):
    state = tmp_path / "state"
    state.mkdir()
    made = _journal(state / "events.sqlite3", time.time())
    assert len(made["week"]) > 250 and made["old_alarm"] not in made["week"]
    endpoint = free_endpoint()
    rec = shared_data / "falls" / "urfd_dev" / "urfd_16_adl.landmarks.jsonl"
    cmd = run_command(["robot_id=longrun", f"pipeline.state_dir={state}", f'zenoh.listen=["{endpoint}"]',
                       "zenoh.event_republish_s=2", "logging.format=json", "source.loop=true",
                       "source.realtime=true", "pipeline.target_fps=5"], source=f"file:{rec}")
    procs.append(subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True))
    web, url = posed_web("longrun", endpoint, 120)
    procs.append(web)
    b = Browser(tmp_path / "profile")
    procs.append(b)
    b.open(url)
    old = json.dumps(made["old_alarm"])
    # the backlog arrives (published at once), and the alarm of 80 days ago (republished until acknowledged)
    n_open = len(made["backlog"]) + 1
    b.wait_for(f"Object.values(posedView.events).filter(e => e.id === {old}).length === 3 && "
               f"new Set(Object.values(posedView.events).map(e => e.id)).size === {n_open}",
               120, "the backlog and the old alarm on the page")
    b.wait_for(f"{ROWS}.length > 1", 60, "the history")
    b.js("document.querySelector('#history-more button').click()")      # show all
    b.wait_for(f"{ROWS}.length === {len(made['week'])}", 60, "every fall of the last 7 days in the history")
    assert b.js("document.getElementById('history-cut').hidden")
    # 120 event messages arrived at once: the page read the robot's journal a few times, not once a message
    time.sleep(3)
    assert b.js("posedView.historyLoads") <= 10
    assert b.js("document.getElementById('alarm').textContent") == f"{n_open} fall event(s) not acknowledged"
    b.js("document.querySelector('#events li.more button').click()")      # show all: the old alarm is there
    b.js(f"document.querySelector('button.ack[data-event-id={old}]').click()")
    b.wait_for(f"posedView.acked[{old}] === true", 30, "the old alarm acknowledged")
    with EventJournal(state / "events.sqlite3", readonly=True) as j:
        assert all(s.acked_at is not None and s.acked_by == "posed web" for s in j.get(made["old_alarm"]))
