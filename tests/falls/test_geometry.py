"""Camera tilt and roll learned from a person walking (falls.camera_tilt_auto / camera_roll_auto).

A synthetic scene with a known tilt and roll: the stick body walks across the room in front of a camera
mounted 1.2 m up, pitched down 15 degrees and rolled 6 degrees. The detector starts from a level camera
(tilt 0, roll 0) and must learn both within 3 degrees, through the real fit (video mode, perspective).
"""

from __future__ import annotations

import numpy as np
import pytest

from posed.bench.falls_body import WorldCamera
from posed.bench.falls_scenarios import frames, make, truth_result, walk
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from posed.falls.geometry import GravityLearner, tilt_roll_deg

TILT, ROLL = 15.0, 6.0


def walking_scene(tilt: float = TILT, roll: float = ROLL, seed: int = 21):
    path = [(-1.4, 3.2), (1.4, 3.4), (1.2, 4.6), (-1.3, 4.4), (-1.2, 3.0), (1.3, 3.1), (0.0, 4.2)]
    sc = make("walk-around", "adl", walk(path), 0.0, 3.5, 1.2, tilt, seed)
    sc.camera = WorldCamera(z=1.2, tilt=tilt, roll=roll)
    return sc


def learn(sc, fit=None, cfg: FallsConfig | None = None) -> FallDetector:
    cfg = cfg or FallsConfig(camera_tilt_deg=0.0, camera_roll_deg=0.0, camera_tilt_auto=True,
                             camera_roll_auto=True, camera_height_m=1.2)
    det = FallDetector(cfg, "r", fit_frame="auto" if fit else "camera")
    size = (sc.camera.width, sc.camera.height)
    for fr in frames(sc):
        res = fit(fr.landmarks, fr.seq, fr.t, size, sc.camera.intrinsics) if fit else truth_result(fr, sc.camera)
        assert det.update(res, fr.landmarks, size, sc.camera.intrinsics) == [], "walking raised an event"
    return det


def test_tilt_and_roll_conventions_round_trip():
    for tilt, roll in ((0.0, 0.0), (15.0, 6.0), (-10.0, -20.0), (40.0, 3.0)):
        assert tilt_roll_deg(gravity_from_tilt(tilt, roll)) == pytest.approx((tilt, roll), abs=1e-9)
        cam = WorldCamera(tilt=tilt, roll=roll)
        down_c = cam.axes @ np.array([0.0, 0.0, -1.0])     # world down in the camera's axes
        np.testing.assert_allclose(down_c, gravity_from_tilt(tilt, roll), atol=1e-12)


def test_learned_from_a_walking_person_through_the_real_fit():
    from posed.bench.falls import real_fitter

    sc = walking_scene()
    det = learn(sc, real_fitter())
    geo = det.geometry
    assert geo["tilt_from"] == "learned" and geo["roll_from"] == "learned"
    assert abs(geo["tilt_deg"] - TILT) < 3.0, geo
    assert abs(geo["roll_deg"] - ROLL) < 3.0, geo


def test_before_convergence_the_configured_geometry_is_used():
    sc = walking_scene()
    cfg = FallsConfig(camera_tilt_deg=4.0, camera_roll_deg=-2.0, camera_tilt_auto=True, camera_roll_auto=True)
    det = FallDetector(cfg, "r", fit_frame="camera")
    size = (640, 480)
    seen = []
    for fr in frames(sc):
        det.update(truth_result(fr, sc.camera), fr.landmarks, size, sc.camera.intrinsics)
        seen.append((det.geometry["standing_s"], det.geometry["tilt_deg"], det.geometry["tilt_from"]))
    early = [s for s in seen if s[0] < 5.0]
    assert early and all(f == "config" and t == pytest.approx(4.0) for _, t, f in early)
    assert seen[-1][2] == "learned" and abs(seen[-1][1] - TILT) < 3.0


def test_only_roll_auto_keeps_the_configured_tilt():
    sc = walking_scene()
    cfg = FallsConfig(camera_tilt_deg=10.0, camera_roll_deg=0.0, camera_roll_auto=True)
    det = learn(sc, cfg=cfg)
    geo = det.geometry
    assert geo["tilt_from"] == "config" and geo["tilt_deg"] == pytest.approx(10.0)
    assert geo["roll_from"] == "learned" and abs(geo["roll_deg"] - ROLL) < 3.0


def test_imu_gravity_overrides_the_learned_one():
    sc = walking_scene()
    det = learn(sc)
    det.set_gravity(gravity_from_tilt(30.0, -4.0) * 9.81)
    assert det.geometry["tilt_from"] == "imu" and det.geometry["tilt_deg"] == pytest.approx(30.0)
    det.set_gravity(np.array([np.nan, 1.0, 0.0]))            # a broken reading changes nothing
    assert det.geometry["tilt_deg"] == pytest.approx(30.0)
    det.set_gravity(None)
    assert det.geometry["tilt_from"] == "learned"


def test_lying_person_is_not_taken_for_the_vertical():
    g0 = gravity_from_tilt(0.0, 0.0)
    learner = GravityLearner(g0)
    horizontal_axis = np.array([1.0, 0.0, 0.0])             # a straight body lying across the image
    assert not learner.add(g0, horizontal_axis, np.array([0.0, 1.0, 0.0]))
    assert learner.samples == 0 and learner.estimate() is None


def test_a_person_in_one_place_fixes_the_roll_not_the_tilt():
    """One image line holds the vertical direction only up to a rotation in its plane: the tilt keeps its
    configured value (no evidence), the roll is learned."""
    tilt, roll = 12.0, 8.0
    g = gravity_from_tilt(tilt, roll)
    prior = gravity_from_tilt(0.0, 0.0)
    learner = GravityLearner(prior)
    # the plane through the camera centre and a vertical segment straight ahead of the camera
    foot = np.array([0.0, 0.0, 4.0]) + 0.8 * g
    head = foot - 1.3 * g
    n = np.cross(foot, head)
    n /= np.linalg.norm(n)
    for _ in range(60):                          # 6 s of standing at 10 fps
        assert learner.add(prior, -g, n)
    est_tilt, est_roll = tilt_roll_deg(learner.estimate())
    assert abs(est_roll - roll) < 1.0
    assert abs(est_tilt) < abs(tilt) - 6.0     # not learned: stays near the configured level camera


class _Log:
    def __init__(self) -> None:
        self.lines: list[tuple[str, dict]] = []

    def warning(self, event, **kw):
        self.lines.append((event, kw))

    error = warning


def test_frame_gravity_reaches_the_detector_through_the_publisher_stage():
    """A landmark frame carrying the IMU's gravity (recording field "gravity") sets the detector's gravity;
    a malformed one is logged and the frame is still judged."""
    from posed.daemon.messages import FitMsg
    from posed.daemon.stages.fall_watch import FallWatch
    from posed.fitting import FitResult
    from posed.landmarks import LandmarkFrame

    log = _Log()
    watch = FallWatch.from_config(FallsConfig(camera_tilt_deg=5.0), "r", log)
    g = gravity_from_tilt(20.0, -3.0) * 9.81
    frame = LandmarkFrame(0, 0.0, None, extra={"gravity": list(g)})
    assert watch.update(FitMsg(FitResult.failure(0, 0.0, "no person"), frame, 0.0, (640, 480))) == []
    geo = watch.detector.geometry
    assert geo["tilt_from"] == "imu" and geo["tilt_deg"] == pytest.approx(20.0) and geo["roll_deg"] == pytest.approx(-3.0)
    bad = LandmarkFrame(1, 0.1, None, extra={"gravity": [1.0, 2.0]})
    assert watch.update(FitMsg(FitResult.failure(1, 0.1, "no person"), bad, 0.1, (640, 480))) == []
    assert watch.bad_gravity == 1 and watch.failures == 0 and log.lines[0][0] == "imu_gravity_bad"
    assert watch.detector.geometry["tilt_deg"] == pytest.approx(20.0)
    off = FallWatch.from_config(FallsConfig(camera_tilt_deg=5.0, imu_gravity=False), "r", log)
    off.update(FitMsg(FitResult.failure(0, 0.0, "no person"), frame, 0.0, (640, 480)))
    assert off.detector.geometry["tilt_from"] == "config" and off.detector.geometry["tilt_deg"] == pytest.approx(5.0)
    status = watch.status()                                   # what the status message carries
    assert status["enabled"] and status["bad_gravity"] == 1 and status["failures"] == 0
    assert status["geometry"]["tilt_from"] == "imu" and status["geometry"]["tilt_deg"] == pytest.approx(20.0)
    assert FallWatch.from_config(FallsConfig(enabled=False), "r", log).status() == {"enabled": False}
