"""The contract fields the daemon stamps on its messages, without a network: unix times computed from the
capture clock when the message is made, the software's version kept apart from the format's, an event
journalled by an older posed still published as a complete posed.fall_event; and the ROS 2 bridge never raising
into the pipeline."""

from __future__ import annotations

import time

import pytest

from posed.client import contract
from posed.daemon import clock
from posed.daemon.bus import payloads
from posed.daemon.bus.ros2 import Ros2Bridge
from posed.daemon.config.sections import Ros2Config
from posed.falls import FallEvent
from tests.daemon.fakes import RecordingLog


def test_stamp_event_moves_capture_times_to_the_wall_clock():
    now = clock.now()
    ev = FallEvent(id="e1", robot="r1", state="falling", t_onset=now - 1.5, t_impact=now - 0.5, t_detect=now,
                   confidence=0.8, features=("pelvis_descent_fast",))
    t0 = time.time()
    out = payloads.stamp_event(ev).to_json()
    assert out["format"] == "posed.fall_event" and out["version"] == contract.VERSION
    assert out["time_unix"] == pytest.approx(t0, abs=0.05)
    assert out["time_unix"] - out["t_onset_unix"] == pytest.approx(1.5, abs=2e-4)
    assert out["t_impact_unix"] - out["t_onset_unix"] == pytest.approx(1.0, abs=2e-4)
    assert contract.errors(payloads.event_message(out)) == []
    # a round trip through the journal's JSON keeps them (FallEvent keeps unknown fields)
    again = FallEvent.from_json(out).to_json()
    assert again["t_onset_unix"] == out["t_onset_unix"] and again["format"] == "posed.fall_event"


def test_an_event_journalled_by_an_older_posed_is_completed():
    old = {"id": "e2", "robot": "r1", "state": "alarm", "t_onset": None, "t_impact": 5.0, "t_detect": 9.0,
           "confidence": 0.9, "features": [], "pose": None, "wall_time": "2026-12-01T10:00:00.250+00:00"}
    out = payloads.event_message(old)
    assert out["time_unix"] == pytest.approx(1796119200.25) and out["format"] == "posed.fall_event"
    assert contract.errors(out) == [] and "format" not in old


def test_status_keeps_the_software_version_apart():
    out = payloads.status_message({"posed_version": "0.1.0", "state": "running"}, "r1", clock.now())
    assert out["version"] == contract.VERSION and out["posed_version"] == "0.1.0"
    assert out["format"] == "posed.status" and out["robot"] == "r1"
    assert out["time_unix"] == pytest.approx(time.time(), abs=0.05)


def test_error_replies_follow_the_schema():
    assert contract.errors(payloads.error_message("limit='x' is not an integer", "limit: integer")) == []


def test_validate_names_what_is_wrong():
    with pytest.raises(ValueError, match="format"):
        contract.validate({"seq": 1})
    assert contract.errors({"format": "posed.pose", "version": 1, "seq": -1, "t": 0.0, "ok": True})
    with pytest.raises(KeyError, match="known"):
        contract.schema("nothing")


class _Pub:
    def __init__(self):
        self.sent = []

    def put(self, payload, attachment=None):
        self.sent.append((payload, attachment))


def test_the_ros2_bridge_counts_what_it_cannot_publish():
    log = RecordingLog()
    bridge = Ros2Bridge(Ros2Config(enabled=True), log)
    for ep in bridge.endpoints.values():
        ep.publisher = _Pub()
    bridge._tokens = [object()]                      # as after open()
    bridge.publish_pose({"ok": True, "time_unix": time.time(), "joint_angles_deg": {"theta_kn_l": "x"},
                         "joints_3d": {"mid_hip": [0, 0, 0]}})      # a non-number angle is left out, not sent
    assert bridge.endpoints["joint_states"].sent == 1 and bridge.errors == 0
    bridge.publish_pose({"ok": True, "time_unix": "not a time", "joint_angles_deg": {}})
    assert bridge.errors == 1 and log.events("error") == ["ros2_publish_failed"]
    bridge.publish_pose({"ok": False, "reason": "no person", "time_unix": time.time()})
    assert bridge.endpoints["skeleton"].sent == 2                      # the skeleton, then its DELETEALL
    assert bridge.status()["published"]["skeleton"] == 2
