"""The message contract on real messages: a replay of the real squat video (real landmark model) and of a real
fall (UR Fall Detection, urfd_02) through ``posed run``; every publication and every query reply is validated
against the shipped JSON Schemas (jsonschema, draft 2020-12) and carries application/json, its format and
version, and a wall-clock time next to the capture-clock time."""

from __future__ import annotations

import json
import time

import pytest
import zenoh

from posed.client import PosedClient, contract
from tests.daemon.zenoh_util import client, free_port, router
from tests.interop.daemons import SQUAT, URFD, Collector, Daemon, fall_overrides, wait_for

JSON = "application/json"
SQUAT_FRAMES = 65


def replies(session, selector: str, timeout: float = 5.0) -> list[tuple[str, str, dict, bool]]:
    """(key or '', encoding, JSON, ok) of every reply."""
    out = []
    for r in session.get(selector, consolidation=zenoh.ConsolidationMode.NONE, timeout=timeout):
        if r.ok is not None:
            out.append((str(r.ok.key_expr), str(r.ok.encoding), json.loads(r.ok.payload.to_string()), True))
        else:
            out.append(("", str(r.err.encoding), json.loads(r.err.payload.to_string()), False))
    return out


def _run(tmp, shared_data, robot, source, length_s, overrides, done):
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    t_start = time.time()
    try:
        with client(rep) as s:
            col = Collector(s, robot)
            d = Daemon(tmp, robot, source, rep, *overrides).start()
            try:
                wait_for(lambda: done(col), 240, f"{robot}'s replay", d)
                got = {"robot": robot, "samples": col.all(), "t_start": t_start, "length_s": length_s,
                       "state": replies(s, f"posed/{robot}/state"),
                       "history_each": replies(s, f"posed/{robot}/events/history/**"),
                       "history_list": replies(s, f"posed/{robot}/events/history"),
                       "history_bad": replies(s, f"posed/{robot}/events/history?limit=many")}
                with PosedClient(s) as c:
                    events = col.on("/events/fall")
                    if events:
                        got["acked"] = c.ack(robot, events[0]["id"], confirm_s=10.0)
                        got["history_after_ack"] = replies(s, f"posed/{robot}/events/history/**")
            finally:
                got_code = d.stop()
            got["exit"] = got_code
            got["t_end"] = time.time()
            return got
    finally:
        r.close()


def _ended(col) -> bool:
    st = col.on("/status")
    return bool(st) and st[-1].get("camera", {}).get("state") == "ended" and len(col.on("/pose")) > 0


@pytest.fixture(scope="module")
def squat(tmp_path_factory, shared_data):
    return _run(tmp_path_factory.mktemp("squat"), shared_data, "squat1", shared_data / SQUAT, SQUAT_FRAMES / 5.0,
                ["zenoh.publish_landmarks=true", "pipeline.status_period_s=0.5"], _ended)


@pytest.fixture(scope="module")
def fall(tmp_path_factory, shared_data):
    def done(col):
        return _ended(col) and col.on("/events/fall")

    return _run(tmp_path_factory.mktemp("fall"), shared_data, "fall1",
                shared_data / URFD / "urfd_02_fall.landmarks.jsonl", 4.0,
                [*fall_overrides(shared_data), "zenoh.publish_landmarks=true", "pipeline.status_period_s=0.5"],
                done)


def _check_published(run) -> dict[str, int]:
    counts: dict[str, int] = {}
    for key, encoding, value in run["samples"]:
        assert encoding == JSON, (key, encoding)
        assert isinstance(value, dict), (key, value)
        problems = contract.errors(value)
        assert problems == [], (key, problems[:5])
        assert value["version"] == contract.VERSION and value["robot"] == run["robot"]
        counts[value["format"]] = counts.get(value["format"], 0) + 1
        # an unpaced replay's capture times follow the recording's time line from its start, so they may run
        # ahead of the wall clock by up to the recording's length
        assert run["t_start"] <= value["time_unix"] <= run["t_end"] + run["length_s"], (key, value["time_unix"])
    return counts


def _check_replies(run) -> None:
    [(key, enc, state, ok)] = run["state"]
    assert ok and enc == JSON and contract.errors(state) == [] and state["format"] == "posed.state"
    assert state["pose"]["format"] == "posed.pose" and state["status"]["format"] == "posed.status"
    for key, enc, obj, ok in run["history_each"]:
        assert ok and enc == JSON and contract.errors(obj) == [] and obj["format"] == "posed.fall_event"
        assert key.endswith(f"/{obj['id']}/{obj['state']}")
    [(key, enc, listing, ok)] = run["history_list"]
    assert ok and enc == JSON and contract.errors(listing) == [] and listing["count"] == len(run["history_each"])
    [(_, enc, err, ok)] = run["history_bad"]
    assert not ok and enc == JSON and contract.errors(err) == [] and "limit" in err["error"]


def test_squat_replay_messages_follow_the_schemas(squat):
    counts = _check_published(squat)
    assert counts["posed.pose"] >= 0.9 * SQUAT_FRAMES and counts["posed.landmarks_frame"] >= 0.9 * SQUAT_FRAMES
    assert counts["posed.status"] >= 1
    poses = [v for _, _, v in squat["samples"] if v["format"] == "posed.pose" and v["ok"]]
    assert poses and all(len(p["joint_angles_deg"]) == 23 and len(p["variables"]) == 19 for p in poses)
    frames = [v for _, _, v in squat["samples"] if v["format"] == "posed.landmarks_frame" and v["landmarks"]]
    assert frames and all(len(v["world"]) == 33 for v in frames)          # BlazePose's world landmarks go out
    _check_replies(squat)
    assert squat["exit"] == 0


def test_fall_replay_messages_follow_the_schemas(fall):
    counts = _check_published(fall)
    assert counts["posed.fall_event"] >= 1 and counts["posed.pose"] > 100
    events = [v for _, _, v in fall["samples"] if v["format"] == "posed.fall_event"]
    for e in events:
        # the unix times are the capture times moved to the wall clock: their differences are the same
        assert e["time_unix"] - e["t_onset_unix"] == pytest.approx(e["t_detect"] - e["t_onset"], abs=2e-3)
    _check_replies(fall)
    assert len(fall["history_each"]) >= 1
    assert fall["acked"] is True
    acked = {(o["id"], o["state"]) for _, _, o, _ in fall["history_after_ack"] if o["acked_at"] is not None}
    assert (events[0]["id"], events[0]["state"]) in acked
    assert fall["exit"] == 0


def test_an_ack_as_the_client_sends_it_follows_the_schema():
    msg = {"format": "posed.ack", "version": 1, "id": "663f78ac3bd54fdeb406273ab0e4dcec", "state": "alarm",
           "time_unix": 1.7e9}
    assert contract.errors(msg) == []
    assert contract.errors({**msg, "state": "asleep"}) and contract.errors({"format": "posed.ack", "version": 1})
