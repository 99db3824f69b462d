"""Two robots on one Zenoh network (a care home: a zenoh-python router on 127.0.0.1, multicast scouting off, two
real ``posed run`` with robot ids r1 and r2, each replaying a real fall of the UR Fall dataset) and two real
``posed web``: one for r1 (a household's page) and one for every robot (``posed web '*'``, a station). Each
page in a headless Chromium: r1's page lists only r1's fall; the station lists both, each entry naming its
robot; an acknowledgement from the station goes to the robot the event is from (its journal, not the other's),
and one from r1's page to r1."""

from __future__ import annotations

import json
import time

import pytest

from posed.daemon.outbox.journal import EventJournal
from tests.daemon.zenoh_util import free_port
from tests.interop.daemons import URFD, Daemon, fall_overrides
from tests.interop.test_fleet import FLEET, fleet_router
from tests.viz.browser import Browser
from tests.viz.web_cli import posed_web

EVENTS = "Object.values(posedView.events)"


def _web(robot: str, endpoint: str, procs: list) -> str:
    proc, url = posed_web(robot, endpoint, 60)
    procs.append(proc)
    return url


def _stored(daemon: Daemon) -> dict[str, list]:
    try:      # created with the robot's first fall event (FileNotFoundError before it, and while being created)
        with EventJournal(daemon.state_dir / "events.sqlite3", readonly=True) as journal:
            out: dict[str, list] = {}
            for s in journal.query():
                out.setdefault(s.event.id, []).append(s)
            return out
    except FileNotFoundError:
        return {}


def _ack(b: Browser, event_id: str) -> None:
    b.js(f"document.querySelector('button.ack[data-event-id={json.dumps(event_id)}]').click()")
    b.wait_for(f"posedView.acked[{json.dumps(event_id)}] === true", 30, f"the acknowledgement of {event_id}")


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_two_robots_one_network_each_event_named_and_acknowledged_on_its_robot(tmp_path, shared_data, procs):
    rep = f"tcp/127.0.0.1:{free_port()}"
    router = fleet_router(rep)
    clips = shared_data / URFD
    robots = [Daemon(tmp_path, "r1", clips / "urfd_02_fall.landmarks.jsonl", rep, *fall_overrides(shared_data),
                     "zenoh.event_republish_s=2", config=FLEET / "robot.yaml"),
              Daemon(tmp_path, "r2", clips / "urfd_04_fall.landmarks.jsonl", rep,
                     *fall_overrides(shared_data, "urfd_04_fall"), "zenoh.event_republish_s=2",
                     config=FLEET / "robot.yaml")]
    try:
        for d in robots:
            procs.append(d.start().proc)
        one, every = Browser(tmp_path / "p1"), Browser(tmp_path / "p2")
        procs.extend([one, every])
        one.open(_web("r1", rep, procs))
        every.open(_web("*", rep, procs))
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and not all(_stored(d) for d in robots):
            time.sleep(1)
        ids = {d.robot: set(_stored(d)) for d in robots}
        assert all(ids.values()), ids
        r1_event, r2_event = sorted(ids["r1"])[0], sorted(ids["r2"])[0]
        # the station lists both robots' falls, each entry saying whose it is
        every.wait_for(f"new Set({EVENTS}.map(e => e.robot)).size === 2", 60, "both robots' events")
        for robot, event_id in (("r1", r1_event), ("r2", r2_event)):
            entry = every.wait_for(f"(document.querySelector('#events li[data-event-id={json.dumps(event_id)}]')"
                                   " || {}).textContent", 30, f"{robot}'s entry")
            assert f"robot {robot} · " in entry
        assert every.js("document.getElementById('robot').textContent").startswith("every robot")
        # r1's page: r1's fall only, named
        one.wait_for(f"{EVENTS}.length > 0", 60, "r1's event on r1's page")
        time.sleep(3)           # r2's messages were published meanwhile (republished every 2 s)
        assert set(one.js(f"{EVENTS}.map(e => e.id)")) <= ids["r1"]
        assert one.js(f"{EVENTS}.every(e => e.robot === 'r1')")
        # the station acknowledges r2's fall: on r2, not on r1
        _ack(every, r2_event)
        assert all(s.acked_at is not None for s in _stored(robots[1])[r2_event])
        assert all(s.acked_at is None for s in _stored(robots[0])[r1_event])
        # r1's page acknowledges r1's: on r1
        _ack(one, r1_event)
        assert all(s.acked_at is not None for s in _stored(robots[0])[r1_event])
        # the station learns it from r1 (acknowledged elsewhere): no button left for it
        every.wait_for(f"posedView.acked[{json.dumps(r1_event)}] === true", 90, "r1's ack seen by the station")
        # the history rows name their robot too
        rows = every.wait_for("[...document.querySelectorAll('#history tr')].slice(1).map(tr => tr.textContent)"
                              ".filter(t => t.includes('robot r2 · '))", 30, "r2's row in the history")
        assert rows
    finally:
        for d in robots:
            d.stop()
        router.close()
