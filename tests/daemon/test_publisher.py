"""The real publisher stage over real Zenoh on 127.0.0.1, fed a scripted fall (perfect fits): pose and
status topics, fall events journalled before publishing and republished when a subscriber appears,
acknowledgement, the state and history queryables, the liveliness token, and a router in between."""

from __future__ import annotations

import json
import sqlite3
import time

import pytest
import zenoh

from tests.daemon.harness import Harness
from tests.daemon.plan_stages import FALL_OVERRIDES
from tests.daemon.redteam_util import until
from tests.daemon.zenoh_util import client, free_port, router


def _daemon(tmp_path, *extra):
    port = free_port()
    ep = f"tcp/127.0.0.1:{port}"
    h = Harness(tmp_path, f"zenoh.listen=[{ep}]", f"pipeline.state_dir={tmp_path / 'state'}", "robot_id=r7",
                "zenoh.event_republish_s=600", *FALL_OVERRIDES, *extra, publisher=True)
    return h, ep


def _collect(session, key):
    got = []
    sub = session.declare_subscriber(key, lambda s: got.append(json.loads(s.payload.to_string())))
    return got, sub



def test_publisher_topics_events_queries_and_ack(tmp_path):
    hook_out = tmp_path / "hook.jsonl"
    h, ep = _daemon(tmp_path, f'hooks.on_event=[{{argv: ["/bin/sh", "-c", "cat >> {hook_out}; echo >> {hook_out}"]}}]')
    try:
        with client(ep) as s:
            poses, _p = _collect(s, "posed/r7/pose")
            statuses, _s = _collect(s, "posed/r7/status")
            landmarks, _l = _collect(s, "posed/r7/landmarks")
            alive = s.liveliness().get("posed/r7/alive", timeout=5)
            assert [str(r.ok.key_expr) for r in alive if r.ok is not None] == ["posed/r7/alive"]
            # the fall happens while nobody listens to events/fall: journalled, not lost
            st = until(lambda: next((x for x in reversed(statuses)
                                      if x.get("events", {}).get("unacknowledged", 0) >= 3), None), 30,
                        "three unacknowledged events in the status")
            assert st["robot"] == "r7" and st["zenoh"]["session"] == "open"
            assert {"capture", "publisher"} <= set(st["stages"]) and st["camera"]["state"] in ("none", "open")
            assert poses and {"seq", "t", "ok", "timing_ms", "time_unix"} <= set(poses[-1])
            assert landmarks and len(landmarks[-1]["landmarks"]) == 33 and landmarks[-1]["image_size"] == [640, 480]
            db = sqlite3.connect(tmp_path / "state" / "events.sqlite3")
            rows = db.execute("SELECT state, published_at FROM messages ORDER BY wall").fetchall()
            assert [r[0] for r in rows] == ["falling", "on_floor", "alarm"]
            # a subscriber appears: the unacknowledged events are published again
            events, _e = _collect(s, "posed/r7/events/fall")
            until(lambda: len(events) >= 3, 5, "republished events")
            assert [e["state"] for e in events[:3]] == ["falling", "on_floor", "alarm"]
            event_id = events[0]["id"]
            assert all(e["id"] == event_id for e in events[:3]) and events[0]["robot"] == "r7"
            # history: one reply per message on distinct keys, or one list on the bare key
            replies = list(s.get("posed/r7/events/history/**?limit=10", consolidation=zenoh.ConsolidationMode.NONE,
                                 timeout=5))
            keys = sorted(str(r.ok.key_expr) for r in replies if r.ok is not None)
            assert keys == sorted(f"posed/r7/events/history/{event_id}/{st}" for st in ("falling", "on_floor",
                                                                                         "alarm"))
            bare = [json.loads(r.ok.payload.to_string()) for r in s.get("posed/r7/events/history?limit=2",
                                                                        timeout=5) if r.ok is not None]
            assert len(bare) == 1 and bare[0]["count"] == 2
            assert [e["state"] for e in bare[0]["events"]] == ["on_floor", "alarm"]
            future = [json.loads(r.ok.payload.to_string()) for r in s.get(
                "posed/r7/events/history?since=2099-01-01", timeout=5) if r.ok is not None]
            assert future[0]["count"] == 0
            bad = list(s.get("posed/r7/events/history?limit=x", timeout=5))
            assert bad and bad[0].err is not None and "limit" in bad[0].err.payload.to_string()
            # state: latest pose and status
            state = [json.loads(r.ok.payload.to_string()) for r in s.get("posed/r7/state", timeout=5)
                     if r.ok is not None]
            assert state and state[0]["pose"]["seq"] >= 0 and state[0]["status"]["robot"] == "r7"
            # acknowledge
            s.put("posed/r7/events/ack", event_id)
            until(lambda: statuses and statuses[-1]["events"]["unacknowledged"] == 0, 5, "acknowledgement")
            acked = db.execute("SELECT count(*) FROM messages WHERE acked_at IS NOT NULL").fetchone()[0]
            assert acked == 3
            # the hook got every event message on stdin; the joint angles went to the history
            until(lambda: hook_out.exists() and len(hook_out.read_text().split()) >= 3, 10, "hook runs")
            hooked = [json.loads(x) for x in hook_out.read_text().splitlines() if x.strip()]
            assert sorted(e["state"] for e in hooked) == ["alarm", "falling", "on_floor"]
            hist = sqlite3.connect(tmp_path / "state" / "history.sqlite3")
            assert hist.execute("SELECT count(*) FROM angles").fetchone()[0] > 0
            gone = []
            _w = s.liveliness().declare_subscriber("posed/r7/alive", lambda smp: gone.append(smp.kind))
            code, _, err, took = h.stop()
            assert code == 0, err
            assert took < 5.0
            until(lambda: zenoh.SampleKind.DELETE in gone, 5, "the alive token to disappear")
    finally:
        if h.proc.poll() is None:
            h.stop()


def test_through_a_router_and_without_one(tmp_path):
    """The daemon as a peer joined to a router (a zenoh-python router session standing in for zenohd): a client
    of the router gets its poses. Then the router goes away and the daemon keeps running."""
    rport = free_port()
    rep = f"tcp/127.0.0.1:{rport}"
    r = router(rep)
    h, ep = _daemon(tmp_path, f"zenoh.connect=[{rep}]")
    try:
        with client(rep) as s:
            poses, _p = _collect(s, "posed/r7/pose")
            until(lambda: len(poses) >= 3, 30, "poses through the router")
        r.close()
        time.sleep(1.0)
        assert h.proc.poll() is None
        before = h.latest()["stages"]["publisher"]["frames"]
        with client(ep) as s:                         # still serving its own listener
            statuses, _s = _collect(s, "posed/r7/status")
            until(lambda: statuses, 5, "status without the router")
        assert h.latest()["stages"]["publisher"]["frames"] >= before
    finally:
        code, _, err, _ = h.stop()
        assert code == 0, err


@pytest.mark.parametrize("mode", ["client"])
def test_no_router_reachable_keeps_running(tmp_path, mode):
    dead = f"tcp/127.0.0.1:{free_port()}"
    h, _ = _daemon(tmp_path, f"zenoh.mode={mode}", f"zenoh.connect=[{dead}]", "zenoh.reconnect_s=0.5")
    try:
        h.wait_for(lambda s: s["ready"] and s["stages"]["publisher"]["frames"] > 20, 30,
                   "frames consumed without a session")
        assert h.latest()["stages"]["publisher"]["restarts"] == 0
    finally:
        code, out, err, _ = h.stop()
    assert code == 0, err
    assert "zenoh_unavailable" in out and "cannot reach" in out


def test_native_zenoh_config_file_is_read_and_posed_keys_win(tmp_path):
    from posed.daemon.bus.session import ZenohConfigError, build_config
    from posed.daemon.config.sections import ZenohConfig

    native = tmp_path / "zenoh.json5"
    native.write_text('{ mode: "router", listen: { endpoints: ["tcp/0.0.0.0:9999"] },\n'
                      '  transport: { auth: { usrpwd: { user: "posed", password: "secret" } } } }\n')
    zc = build_config(ZenohConfig(config_file=str(native)))
    assert json.loads(zc.get_json("transport/auth/usrpwd/user")) == "posed"       # from the file
    assert json.loads(zc.get_json("mode")) == "peer"                               # posed's keys win
    assert json.loads(zc.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert json.loads(zc.get_json("scouting/multicast/enabled")) is False
    bad = tmp_path / "bad.json5"
    bad.write_text("{ mode: ")
    with pytest.raises(ZenohConfigError, match="not a valid Zenoh config"):
        build_config(ZenohConfig(config_file=str(bad)))
