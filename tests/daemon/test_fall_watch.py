"""Fall detection in the publisher stage: every frame reaches the detector with its landmarks, image size and
intrinsics; a detector that raises costs that frame's events only, counted and logged sparingly."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from posed.daemon.stages.fall_watch import FallWatch
from posed.falls import FallsConfig
from tests.daemon.fakes import RecordingLog


def fit_msg(seq: int):
    result = SimpleNamespace(seq=seq, t=seq / 30.0, extra={})
    return SimpleNamespace(result=result, landmarks=SimpleNamespace(landmarks=np.zeros((33, 5))), others=(),
                           image_size=(640, 480), intrinsics=SimpleNamespace(fx=500.0, fy=500.0, cx=320.0, cy=240.0))


class Detector:
    cfg = FallsConfig()

    def __init__(self, fail: bool = False) -> None:
        self.fail = fail
        self.calls: list[tuple] = []

    def update(self, result, landmarks, image_size, intrinsics=None):
        self.calls.append((result.seq, landmarks.shape, image_size, intrinsics))
        if self.fail:
            raise ZeroDivisionError("bug")
        return [f"event-{result.seq}"]


def test_every_frame_reaches_the_detector():
    det = Detector()
    watch = FallWatch(det, RecordingLog())
    msg = fit_msg(3)
    assert watch.update(msg) == ["event-3"]
    assert det.calls == [(3, (33, 5), (640, 480), msg.intrinsics)]


def test_a_failing_detector_costs_only_its_frames():
    errors, log = [], RecordingLog()
    watch = FallWatch(Detector(fail=True), log, on_error=lambda: errors.append(1))
    assert all(watch.update(fit_msg(i)) == [] for i in range(250))
    assert watch.failures == 250 and len(errors) == 250
    logged = [f["failures"] for lv, e, f in log.lines if e == "fall_detector_failed"]
    assert logged == [1, 2, 3, 100, 200]


def test_disabled_falls_give_no_events():
    watch = FallWatch.from_config(FallsConfig(enabled=False), "r1", RecordingLog())
    assert watch.detector is None and watch.update(fit_msg(0)) == []
    assert FallWatch.from_config(FallsConfig(), "r1", RecordingLog()).detector is not None


def test_with_a_household_the_history_follows_the_member_not_the_frames_own_person():
    """Two people through FallWatch as the publisher feeds it (FitMsg with ``others``, frames with ``people``):
    the member (1.60 m, not the frame's own person) is what the history keeps; with only the visitor in view,
    a "no person" result; the status lists who is who."""
    from dataclasses import replace

    from posed.bench.falls_body import Body
    from posed.bench.falls_scenarios import STAND, Key, Truth, frames, make, truth_result
    from posed.daemon.messages import FitMsg
    from posed.falls.config import HouseholdMember
    from posed.landmarks.recording import LandmarkFrame, PersonLandmarks

    def still(height, xy, seed):
        sc = make("s", "adl", ([Key(0.0, STAND, xy=xy), Key(3.0, STAND, xy=xy, ease="hold")], Truth("adl")),
                  0.0, 3.0, 1.0, 12.0, seed=seed, start_xy=xy)
        return replace(sc, body=Body(height))

    member, visitor = still(1.60, (-0.9, 3.2), 1), still(1.84, (0.9, 3.4), 2)
    cam = member.camera
    cfg = FallsConfig(camera_tilt_deg=12.0, camera_height_m=1.0, camera_geometry="measured",
                      household=(HouseholdMember("Grandma", 1.60),))
    watch = FallWatch.from_config(cfg, "r1", RecordingLog())
    kept = []
    for m, v in zip(frames(member), frames(visitor), strict=True):
        rv = replace(truth_result(v, cam), extra={"person": 1})
        rm = replace(truth_result(m, cam), extra={"person": 2})
        frame = LandmarkFrame(m.seq, m.t, v.landmarks, people=(PersonLandmarks(1, v.landmarks),
                                                               PersonLandmarks(2, m.landmarks)))
        msg = FitMsg(rv, frame, m.t, (cam.width, cam.height), (), cam.intrinsics, others=(rm,))
        watch.update(msg)
        kept.append(watch.followed(msg))
    assert kept[-1].extra.get("person") == 2 and kept[0].extra.get("person") == 1   # before she was known
    status = watch.status()["household"]
    assert status["followed"] == 2 and status["members"] == ["Grandma"]
    who = {p["person"]: p for p in status["in_view"]}
    assert who[2]["member"] == "Grandma" and who[1]["visitor"] and abs(who[1]["stature_m"] - 1.84) < 0.03
    # the visitor alone: the person cared for is not in view
    alone = FitMsg(rv, LandmarkFrame(99, 9.9, v.landmarks, people=(PersonLandmarks(1, v.landmarks),)), 9.9,
                   (cam.width, cam.height), (), cam.intrinsics)
    watch.update(replace(alone, result=replace(rv, seq=99, t=9.9)))
    got = watch.followed(alone)
    assert not got.ok and got.reason == "no person"


class TickingDetector(Detector):
    """A detector whose timer raises an alarm at a tick."""

    robot_id = "r1"
    state = "down"
    event_id = None

    def tick(self, t):
        from posed.falls import FallEvent

        self.calls.append(("tick", t))
        if self.fail:
            raise ZeroDivisionError("bug")
        return [FallEvent("ev", "r1", "alarm", 1.0, 2.0, t, 0.9)]


def test_a_tick_runs_the_timers_without_a_frame_and_says_so():
    det = TickingDetector()
    watch = FallWatch(det, RecordingLog())
    (alarm,) = watch.tick(15.0, 3.25)
    assert det.calls == [("tick", 15.0)]
    assert alarm.state == "alarm" and alarm.t_detect == 15.0 and alarm.extra == {"without_frames_s": 3.25}
    errors, log = [], RecordingLog()
    failing = FallWatch(TickingDetector(fail=True), log, on_error=lambda: errors.append(1))
    assert failing.tick(15.0, 3.0) == [] and failing.failures == 1 and errors == [1]
    assert FallWatch.from_config(FallsConfig(enabled=False), "r1", RecordingLog()).tick(1.0, 9.0) == []


def test_the_publisher_ticks_the_timers_only_after_the_blind_threshold_on_the_capture_clock():
    """PublisherStage.falls_between_frames: no tick while frames come (within the supervisor's blind threshold,
    3 s); then the timers run to the monotonic now, or for an unpaced replay (capture clock ahead of it) to the
    last frame's capture time plus the time since; every message goes to the outbox."""
    from posed.daemon.proc.blind import blind_after_s
    from posed.daemon.stages.publish import PublisherStage
    from posed.daemon.stages.restored_falls import RestoredFalls

    posted = []
    det = TickingDetector()
    stage = PublisherStage.__new__(PublisherStage)
    stage.falls = FallWatch(det, RecordingLog())
    stage.restored = RestoredFalls([], FallsConfig(), RecordingLog())
    stage.outbox = SimpleNamespace(post=posted.append)
    stage.tick_after_s = blind_after_s(10.0)
    assert stage.tick_after_s == 3.0
    stage._frame_at, stage._frame_t = 100.0, 99.9          # live: captured 0.1 s before it was handled
    stage.falls_between_frames(102.9)
    assert det.calls == [] and posted == []
    stage.falls_between_frames(103.0)
    assert det.calls == [("tick", 103.0)] and posted[0].extra["without_frames_s"] == 3.0
    assert posted[0].extra["time_unix"] is not None           # stamped before the journal
    stage._frame_at, stage._frame_t = 100.0, 500.0          # unpaced replay: the capture clock runs ahead
    stage.falls_between_frames(104.0)
    assert det.calls[-1] == ("tick", 504.0)
