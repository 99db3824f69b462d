"""The alarm timer without frames (FallDetector.tick, PeopleFalls.tick): the alarm comes when due although no
frame arrives; it is the alarm a frame without a person would have raised at that time; a frame that comes
later, even with an older capture time, neither undoes nor repeats it; a tick behind the frames does nothing.
Ground-truth fits of a simulated fall (bench.falls_scenarios), as tests/falls/test_people.py."""

from __future__ import annotations

from dataclasses import replace

from posed.falls.detector import FallDetector
from posed.falls.people import PeopleFalls
from posed.fitting import FitResult
from tests.falls.test_people import FALL, HELDOUT, cfg_for, detector, frames, truth_result, two_streams

ALARM_S = 5.0


def _until_on_floor(det: FallDetector, sc):
    """Feed the fall up to its on_floor message (then the frames stop: the camera went blind)."""
    cam = sc.camera
    size = (cam.width, cam.height)
    out = []
    for fr in frames(sc):
        out += det.update(truth_result(fr, cam), fr.landmarks, size, cam.intrinsics)
        if any(e.state == "on_floor" for e in out):
            return out, fr
    raise AssertionError("no on_floor")


def test_the_alarm_comes_when_due_without_frames_as_a_frame_without_a_person_would_raise_it():
    sc = HELDOUT[FALL]
    cfg = cfg_for(sc, alarm_after_s=ALARM_S)
    ticked, framed = detector(cfg), detector(cfg)
    out, last = _until_on_floor(ticked, sc)
    _until_on_floor(framed, sc)
    t_impact = out[0].t_impact
    due = t_impact + ALARM_S
    assert last.t < due - 1.0
    assert ticked.tick(due - 0.01) == []
    (alarm,) = ticked.tick(due)
    size = (sc.camera.width, sc.camera.height)
    (same,) = framed.update(FitResult.failure(last.seq + 1, due, "no person"), None, size, sc.camera.intrinsics)
    # the very message (ids from the same counter); the tick's also keeps the last judged frame's pelvis height
    # and trunk inclination (the frame without a person came after a gap: the detector forgot the motion)
    assert replace(alarm, extra=same.extra) == same and same.extra.items() <= alarm.extra.items()
    assert alarm.state == "alarm" and alarm.t_detect == due and ticked.state == "alarm"
    assert ticked.tick(due + 10.0) == []          # once
    # a frame that comes later with an older capture time (stalled in the pipeline): nothing undone or repeated
    later = replace(last, seq=last.seq + 1, t=last.t + 0.1)
    assert ticked.update(truth_result(later, sc.camera), later.landmarks, size, sc.camera.intrinsics) == []
    assert ticked.state == "alarm" and ticked.event_id == alarm.id
    newer = replace(last, seq=last.seq + 2, t=due + 1.0)
    assert ticked.update(truth_result(newer, sc.camera), newer.landmarks, size, sc.camera.intrinsics) == []


def test_a_tick_behind_the_frames_or_with_no_event_does_nothing():
    sc = HELDOUT[FALL]
    det = detector(cfg_for(sc, alarm_after_s=ALARM_S))
    assert det.tick(1e6) == []                    # nothing under way
    out, last = _until_on_floor(det, sc)
    assert det.tick(last.t - 0.5) == []           # behind the last frame (an unpaced replay's clock)
    assert det.tick(out[0].t_impact + ALARM_S + 1.0)[0].state == "alarm"


def test_every_person_gets_the_tick_and_a_later_older_frame_is_no_restart_of_the_stream():
    sc = HELDOUT[FALL]
    cfg = cfg_for(sc, alarm_after_s=ALARM_S)
    events, watch = two_streams(sc, cfg=cfg)
    assert [e.state for e in events] == ["falling", "on_floor"] and events[0].extra["person"] == 2
    last_t = watch._prev_t
    due = events[0].t_impact + ALARM_S
    assert due > last_t
    (alarm,) = watch.tick(due)
    assert alarm.state == "alarm" and alarm.extra["person"] == 2 and alarm.id == events[0].id
    assert watch.tick(due + 1.0) == []
    # the next frame's capture time is before the tick's: both people kept, nothing raised again
    cam = sc.camera
    fr = replace(list(frames(sc))[-1], t=last_t + 0.1, seq=10_000)
    r = replace(truth_result(fr, cam), extra={"person": 2})
    assert watch.update([(1, r, fr.landmarks), (2, r, fr.landmarks)], fr.t, fr.seq, (cam.width, cam.height),
                        cam.intrinsics) == []
    assert set(watch.people) == {1, 2} and watch.people[2].detector.state == "alarm"


def test_one_person_without_ids_ticks_as_a_single_detector():
    sc = HELDOUT[FALL]
    cfg = cfg_for(sc, alarm_after_s=ALARM_S)
    alone, people = detector(cfg), PeopleFalls(detector(cfg), lambda: detector(cfg))
    cam = sc.camera
    size = (cam.width, cam.height)
    out = []
    for fr in frames(sc):
        r = truth_result(fr, cam)
        alone.update(r, fr.landmarks, size, cam.intrinsics)
        out += people.update([(None, r, fr.landmarks)], fr.t, fr.seq, size, cam.intrinsics)
        if any(e.state == "on_floor" for e in out):
            break
    due = out[0].t_impact + ALARM_S
    assert people.tick(due) == alone.tick(due) != []
