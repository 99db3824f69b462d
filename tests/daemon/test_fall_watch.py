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
