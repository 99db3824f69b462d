"""A fleet on 127.0.0.1: a zenoh-python session in router mode opened from deploy/fleet/router.json5 (the
stand-in for zenohd), three ``posed run`` configured from deploy/fleet/robot.yaml with three robot ids, and a
caregiver's station using the client. One robot falls, is killed with SIGKILL before anyone acknowledged the
event, and is started again on the same state dir (a daily-activity clip this time, no new fall): its
unacknowledged event reaches the station again, from the journal, and the station acknowledges it."""

from __future__ import annotations

import json
import threading
import time

import pytest
import zenoh

from posed.client import Alive, PosedClient
from tests.daemon.zenoh_util import free_port
from tests.interop.daemons import ROOT, URFD, Daemon, fall_overrides, wait_for

FLEET = ROOT / "deploy" / "fleet"
ADL = "urfd_16_adl.landmarks.jsonl"


def fleet_router(endpoint: str) -> zenoh.Session:
    cfg = zenoh.Config.from_file(str(FLEET / "router.json5"))
    cfg.insert_json5("listen/endpoints", json.dumps([endpoint]))
    return zenoh.open(cfg)


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_three_robots_a_router_and_a_station(tmp_path, shared_data):
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = fleet_router(rep)
    clips = shared_data / URFD
    light = ["source.loop=true", "source.realtime=true", "pipeline.target_fps=5"]
    faller = Daemon(tmp_path, "r1", clips / "urfd_02_fall.landmarks.jsonl", rep, *fall_overrides(shared_data),
                    config=FLEET / "robot.yaml")
    others = [Daemon(tmp_path, rid, clips / ADL, rep, *light, config=FLEET / "robot.yaml") for rid in ("r2", "r3")]
    restarted = None
    lock = threading.Lock()
    events: list[tuple[float, str, object]] = []
    alive: list[Alive] = []
    poses: dict[str, int] = {}

    def on_event(robot, e):
        with lock:
            events.append((time.monotonic(), robot, e))

    def on_pose(robot, fit):
        with lock:
            poses[robot] = poses.get(robot, 0) + 1

    try:
        with PosedClient.connect(rep, wait_s=10) as station:
            station.on_event("*", on_event)
            station.on_pose("*", on_pose)
            station.on_alive(alive.append)
            for d in (*others, faller):
                d.start()
            wait_for(lambda: station.robots() == ["r1", "r2", "r3"], 180, "three robots up", faller)
            wait_for(lambda: all(poses.get(x, 0) >= 3 for x in ("r1", "r2", "r3")), 120, "poses of each robot")
            first = wait_for(lambda: [e for _, rb, e in events if rb == "r1"], 180, "r1's fall event", faller)[0]
            assert first.robot == "r1" and first.extra["format"] == "posed.fall_event"
            history = wait_for(lambda: [h for h in station.history("*") if h.event.id == first.id], 10,
                               "the event in r1's history")
            assert all(h.acked_at is None and h.robot == "r1" for h in history)

            faller.kill()                                           # SIGKILL: nobody acknowledged the event
            wait_for(lambda: Alive("r1", False) in alive, 30, "r1 gone")
            assert station.robots() == ["r2", "r3"]
            t_back = time.monotonic()
            restarted = Daemon(tmp_path, "r1", clips / ADL, rep, *light, state_dir=faller.state_dir,
                               config=FLEET / "robot.yaml").start()
            again = wait_for(lambda: [e for t, rb, e in events if rb == "r1" and t > t_back and e.id == first.id],
                             120, "r1's unacknowledged event again, after its restart", restarted)
            assert again[0].extra["time_unix"] == first.extra["time_unix"]   # the same message, from the journal
            assert station.robots() == ["r1", "r2", "r3"]
            assert station.ack("r1", first.id, by="station", confirm_s=15.0)
            after = [h for h in station.history("r1") if h.event.id == first.id]
            assert after and all(h.acked_at is not None for h in after)
            # the other robots kept publishing meanwhile, and history reads across robots
            assert {h.robot for h in station.history("*", limit=1000)} <= {"r1", "r2", "r3"}
    finally:
        for d in (faller, *others, restarted):
            if d is not None:
                d.stop()
        r.close()
