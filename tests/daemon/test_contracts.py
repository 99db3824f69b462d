import json
import pickle

import pytest

from posed.camera_model import Intrinsics
from posed.daemon.messages import FrameRef, StageHealth, origin
from posed.falls import FallEvent
from posed.fitting import JOINT_3D_NAMES, JOINT_ANGLE_NAMES, VARIABLE_NAMES, FitResult


def _via_json(obj):
    return json.loads(json.dumps(obj.to_json()))


def test_frame_ref_and_health_round_trip():
    ref = FrameRef(slot=2, seq=17, t_capture=123.456, width=640, height=480, has_depth=True)
    assert FrameRef.from_json(_via_json(ref)) == ref
    assert origin(ref) == 123.456
    # what the capture stage sends for an unpaced replay with a known camera, through JSON and the mailboxes
    ref = FrameRef(slot=1, seq=3, t_capture=1.5, width=640, height=480,
                   intrinsics=Intrinsics(600.0, 601.0, 319.5, 239.5, 640, 480), t_origin=9.25)
    assert FrameRef.from_json(_via_json(ref)) == ref == pickle.loads(pickle.dumps(ref, protocol=5))
    assert origin(ref) == 9.25
    health = StageHealth("landmarks", 42, 10.5, None, 100, drops=3)
    assert StageHealth.from_json(_via_json(health)) == health


def test_fit_result_matches_interfaces_and_round_trips():
    assert len(VARIABLE_NAMES) == 19 and len(JOINT_ANGLE_NAMES) == 23 and len(JOINT_3D_NAMES) == 13
    res = FitResult(seq=0, t=0.0, ok=True, loss=0.0067, fit_ms=0.9,
                    variables={n: float(i) for i, n in enumerate(VARIABLE_NAMES)},
                    joint_angles_deg={n: 1.5 for n in JOINT_ANGLE_NAMES},
                    joints_3d={n: (0.1, -0.2, 0.3) for n in JOINT_3D_NAMES}, extra={"mode": "video"})
    obj = _via_json(res)
    assert set(obj) >= {"seq", "t", "ok", "loss", "fit_ms", "variables", "joint_angles_deg", "joints_3d"}
    assert obj["joints_3d"]["mid_hip"] == [0.1, -0.2, 0.3]
    assert FitResult.from_json(obj) == res


def test_fit_failure_carries_reason():
    bad = FitResult.failure(5, 0.5, "no person")
    obj = _via_json(bad)
    assert obj == {"seq": 5, "t": 0.5, "ok": False, "reason": "no person"}
    assert FitResult.from_json(obj) == bad
    with pytest.raises(ValueError, match="ok must be bool"):
        FitResult.from_json({"seq": 1, "t": 0.0, "ok": "yes"})


def test_fall_event_round_trip_and_state_check():
    ev = FallEvent(id=FallEvent.new_id(), robot="r1", state="alarm", t_onset=1.0, t_impact=1.6, t_detect=1.9,
                   confidence=0.93, features=("trunk_inclination", "pelvis_drop"), pose={"seq": 3, "ok": True},
                   wall_time="2026-11-22T10:00:00Z")
    assert FallEvent.from_json(_via_json(ev)) == ev
    with pytest.raises(ValueError, match="not one of: falling, on_floor, alarm, recovered"):
        FallEvent.from_json({**ev.to_json(), "state": "panic"})
