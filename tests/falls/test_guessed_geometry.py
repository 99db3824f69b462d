"""A camera nobody measured (issue 33): the default config (tilt 0, height 1 m) is a guess, checked against the
person's own body; and falls that end out of sight within a few frames of the impact, judged on the descent.

The detector runs on ground-truth fits of the simulated body (``truth_result``) so each rule is tested alone;
the real fit on these scenes is measured by ``posed bench falls --mount wall --synthetic-geometry default``.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.daemon.bus.payloads import event_message
from posed.falls import detector as detector_module
from posed.falls.camera_geometry import CameraGeometry
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector

WALL = {sc.name: sc for sc in catalogue("tune", "wall")}
TUNE = {sc.name: sc for sc in catalogue("tune")}
WALL_FALLS = ["wall/tune/fall/standing-sideways/fast-v30", "wall/tune/fall/standing-backward/fast-v100",
              "wall/tune/fall/standing-forward/fast-v100"]


def run(sc, cfg: FallsConfig, intrinsics: bool = False, lose_after: float | None = None,
        end_after: float | None = None):
    counter = itertools.count()
    det = FallDetector(cfg, "r1", fit_frame="camera", id_factory=lambda: f"ev{next(counter)}")
    out = []
    for fr in frames(sc):
        if end_after is not None and fr.t > end_after + 1e-9:
            break                                       # the recording ends
        lm = None if lose_after is not None and fr.t >= lose_after else fr.landmarks
        res = truth_result(replace(fr, landmarks=lm), sc.camera)
        out += det.update(res, lm, (sc.camera.width, sc.camera.height),
                          intrinsics=sc.camera.intrinsics if intrinsics else None)
    return det, out


def test_the_configured_geometry_is_a_guess_only_at_its_defaults():
    assert not CameraGeometry(FallsConfig()).measured
    assert CameraGeometry(FallsConfig(camera_height_m=0.85)).measured
    assert CameraGeometry(FallsConfig(camera_tilt_deg=12.0)).measured
    assert CameraGeometry(FallsConfig(camera_geometry="measured")).measured
    assert not CameraGeometry(FallsConfig(camera_tilt_deg=12.0, camera_geometry="guess")).measured
    # each value on its own: a height set with the tilt and roll left at 0 trusts the height, not the tilt
    assert not CameraGeometry(FallsConfig(camera_height_m=0.85)).tilt_measured
    assert CameraGeometry(FallsConfig(camera_roll_deg=-3.0)).tilt_measured
    assert CameraGeometry(FallsConfig(camera_geometry="measured")).tilt_measured


def test_a_configured_height_is_kept_while_a_tilt_left_at_0_is_checked_against_the_body():
    """A wall camera 2 m up, 35 deg down, configured with its height only (the tilt left at 0): the standing
    body rejects the level tilt, and the configured 2 m stays the floor along the body's gravity (before, a
    height alone made the tilt 0 trusted as well, and a wall camera caught 5 of 111 simulated falls). A tilt
    that was configured is never checked."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    geo = CameraGeometry(FallsConfig(camera_height_m=2.0))
    for _ in range(30):                                           # 3 s standing, feet not in view
        geo.observe_body_axis(-down, 0.1)
    assert geo.used() == {"gravity": "body", "floor": "config", "config": "measured"}
    assert np.degrees(np.arccos(np.clip(geo.gravity @ down, -1.0, 1.0))) < 3.5
    assert geo.floor_below_camera == 2.0 and geo.metric_floor() == 2.0
    told = CameraGeometry(FallsConfig(camera_tilt_deg=5.0, camera_height_m=2.0))
    for _ in range(30):
        told.observe_body_axis(-down, 0.1)
    assert told.used()["gravity"] == "config" and told.floor_below_camera == 2.0


@pytest.mark.parametrize("name", WALL_FALLS)
def test_a_wall_camera_fall_is_caught_with_the_default_config(name):
    """A camera 2 m up, 35 deg down, 320x240, no intrinsics, the config told nothing: the standing body
    contradicts the level guess, its axis gives gravity and its feet the floor. Trusting the same default values
    as measured (the detector before issue 33) misses the fall."""
    sc = WALL[name]
    det, events = run(sc, FallsConfig())
    first = next(e for e in events if e.state in ("falling", "on_floor"))
    assert 0.0 <= first.t_detect - sc.truth.t_impact <= 1.5
    assert first.extra["geometry"] == {"gravity": "body", "floor": "learned", "config": "guess",
                                      "lens": "assumed"}   # a wall camera without intrinsics
    assert det.geometry["tilt_from"] == "body" and abs(det.geometry["tilt_deg"] - sc.camera.tilt) < 6.0
    _, trusted = run(sc, FallsConfig(camera_geometry="measured"))
    assert not [e for e in trusted if e.state in ("falling", "on_floor")]


def test_the_event_says_which_geometry_it_used_in_its_message():
    sc = WALL[WALL_FALLS[0]]
    _, events = run(sc, FallsConfig())
    msg = json.loads(json.dumps(event_message(events[0].to_json())))
    assert msg["geometry"]["gravity"] == "body" and msg["geometry"]["config"] == "guess"
    _, events = run(TUNE["tune/fall/standing-sideways/fast-v100"],
                    FallsConfig(camera_tilt_deg=TUNE["tune/fall/standing-sideways/fast-v100"].camera.tilt,
                                camera_height_m=1.2), intrinsics=True)
    assert events[0].extra["geometry"]["config"] == "measured"
    assert events[0].extra["geometry"]["gravity"] == "config"


def test_a_body_that_agrees_with_the_guess_keeps_it():
    """The robot's camera 12 deg down with a level guess: within BODY_REJECT_DEG, so the guess (and its
    configured height) stays; the fit's body axis is not precise enough to correct a small error."""
    sc = TUNE["tune/adl/squat/normal-v30"]
    assert sc.camera.tilt == pytest.approx(12.0)
    det, events = run(sc, FallsConfig(), intrinsics=True)
    assert events == []
    assert det.geometry["tilt_from"] == "config" and det.geometry["tilt_deg"] == pytest.approx(0.0)


def test_wall_camera_daily_activities_raise_nothing_with_the_default_config():
    for name in ("wall/tune/adl/sit-down-chair/normal-v30", "wall/tune/adl/lie-on-bed-side/normal-v30",
                 "wall/tune/adl/squat/quick-v100", "wall/tune/adl/bend-pick-up/normal-v30"):
        _, events = run(WALL[name], FallsConfig())
        assert events == [], name


FAST_FALLS = ["tune/fall/standing-sideways/fast-v100", "tune/fall/standing-forward/fast-v30",
              "tune/fall/standing-backward/fast-v100"]


@pytest.mark.parametrize("name", FAST_FALLS)
def test_a_fall_lost_at_the_impact_is_judged_on_the_descent_before_the_recording_ends(name):
    """Lost one frame after the impact, and the recording ends 0.3 s later (before lost_confirm_s): the
    descent itself decides, with the feature judged_on_descent and a lower confidence."""
    sc = TUNE[name]
    cfg = FallsConfig(camera_tilt_deg=sc.camera.tilt, camera_height_m=sc.camera.z)
    last_seen = sc.truth.t_impact + 0.1
    _, events = run(sc, cfg, intrinsics=True, lose_after=last_seen + 0.05, end_after=last_seen + 0.3)
    assert events, "a fall lost at the impact raised nothing before the recording ended"
    first = events[0]
    assert first.state == "falling"
    assert "judged_on_descent" in first.features and "lost_after_descent" in first.features
    assert first.confidence <= 0.75
    assert first.t_detect - last_seen <= cfg.lost_descent_confirm_s + 0.1 + 1e-9


def test_one_dropped_frame_in_a_fall_like_descent_is_not_a_decision():
    """lost_descent_confirm_s is more than one frame period: a single missing frame decides nothing."""
    sc = TUNE[FAST_FALLS[0]]
    cfg = FallsConfig(camera_tilt_deg=sc.camera.tilt, camera_height_m=sc.camera.z)
    last_seen = sc.truth.t_impact + 0.1
    _, events = run(sc, cfg, intrinsics=True, lose_after=last_seen + 0.05, end_after=last_seen + 0.1)
    assert events == []


def _jump_down_from_a_platform(height: float = 1.6):
    """Standing on a platform ``height`` m up for 2 s (the floor is learned there), then jumping down in front
    of it (0.3 s, a free fall's speed) and standing on the real floor, the legs hidden behind its edge, as the
    man in the shared data's s2d_enter video jumps off a block."""
    import math

    import numpy as np

    from posed.bench.falls_body import Body, RestingPlace, WorldCamera, place
    from posed.bench.falls_scenarios import STAND, Frame

    cam, body, rng = WorldCamera(z=2.0, tilt=10.0), Body(), np.random.default_rng(3)
    out = []
    for k in range(51):
        t = k / 10
        w = min(max((t - 2.0) / 0.3, 0.0), 1.0)
        lift = height * (1 - w * w) + (0.05 * math.sin(math.pi * w) if 0 < w < 1 else 0.0)
        joints = place(STAND, body, RestingPlace(0.0, 5.0 - 0.5 * w, None, lift))
        lm = cam.project(joints, body, rng, 0.01)
        if w > 0:
            lm[25:33, 3] = 0.1                  # behind the platform's edge: knees and feet hidden
        out.append(Frame(k, t, lm, joints))
    return cam, out


def test_coming_down_to_another_level_is_not_a_fall(monkeypatch):
    """A pelvis far below the floor learned from the feet (BELOW_FLOOR_REL) is another level, not a fall; with
    that rule off, the same jump is taken for a fall onto the floor."""
    import posed.falls.detector as detector

    cam, frs = _jump_down_from_a_platform()

    def events(cfg):
        det = FallDetector(cfg, "r1", fit_frame="camera")
        out = []
        for fr in frs:
            out += det.update(truth_result(fr, cam), fr.landmarks, (cam.width, cam.height), cam.intrinsics)
        return det, out

    cfg = FallsConfig(camera_tilt_deg=cam.tilt, camera_height_m=cam.z)
    det, out = events(cfg)
    assert out == [] and det.other_level > 0
    monkeypatch.setattr(detector, "BELOW_FLOOR_REL", 10.0)
    _, out = events(cfg)
    assert [e.state for e in out][:1] == ["falling"]


def test_a_seated_persons_feet_give_the_floor_when_the_guess_is_rejected():
    """A wall camera 35 deg down, the config told nothing, a person only ever seen sitting (a fall from a
    chair): their trunk rejects the level guess, and their feet, on the floor as a standing person's are,
    give the floor along the body's gravity (before, nothing did: heights were then taken from the lowest
    joint, and a fall from the chair lay at half a standing pelvis height)."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])          # gravity in camera axes
    ahead = np.array([0.0, -np.sin(tilt), np.cos(tilt)])         # level, away from the camera
    ankle_height = 0.08
    ankles = 3.0 * ahead + (2.0 - ankle_height) * down            # the floor 2 m below the camera
    geo = CameraGeometry(FallsConfig())
    assert not geo.measured and geo.floor_below_camera == pytest.approx(1.0)   # the guess: level, 1 m
    for _ in range(30):                                           # 3 s sitting at 10 fps
        geo.observe_seated_trunk(-down, 0.1, ankles, ankle_height)
    assert geo.used() == {"gravity": "body", "floor": "learned", "config": "guess"}
    assert np.degrees(np.arccos(np.clip(geo.gravity @ down, -1.0, 1.0))) < 3.5     # within the body's step
    assert geo.floor_below_camera == pytest.approx(2.0, abs=0.15)
    # the same sitting without the feet in view: the guess is rejected and no floor is known
    blind = CameraGeometry(FallsConfig())
    for _ in range(30):
        blind.observe_seated_trunk(-down, 0.1)
    assert blind.used()["gravity"] == "body" and blind.floor_below_camera is None


def test_a_fall_from_a_chair_on_a_wall_camera_is_judged_on_the_floor_under_the_seated_feet():
    """The whole detector on a simulated fall from a chair, the wall camera and the default config: the event
    says the floor was learned (under the seated person's feet), not taken from the lowest joint."""
    sc = WALL["wall/tune/fall/sitting-forward/fast-v30"]
    _, events = run(sc, FallsConfig())
    first = next(e for e in events if e.state in ("falling", "on_floor"))
    assert first.extra["geometry"]["gravity"] == "body" and first.extra["geometry"]["floor"] == "learned"


def test_a_seated_persons_feet_teach_a_measured_mount_its_floor():
    """The wall camera measured (35 deg, 2 m) but its lens assumed: the person's metres come out some 15 %
    short, so under the configured 2 m a person who only sat before falling from the chair lies well above the
    floor. Their feet rest on the floor as a standing person's do: the floor is learned from them, and the fall
    is caught, judged on that floor."""
    sc = WALL["wall/tune/fall/sitting-sideways/fast-v30"]
    det, events = run(sc, FallsConfig(camera_tilt_deg=35.0, camera_height_m=2.0))
    first = next(e for e in events if e.state in ("falling", "on_floor"))
    assert 0.0 <= first.t_detect - sc.truth.t_impact <= 1.5
    assert first.extra["geometry"]["floor"] == "learned" and first.extra["geometry"]["gravity"] == "config"
    assert det.camera.floor_below_camera < 1.85     # the fit's metres, not the configured 2 m


def test_seated_feet_teach_the_floor_under_the_guess_too(monkeypatch):
    """A seated person's feet rest on the floor as a standing person's do: they teach it along whatever gravity
    is in use, the level guess as much as a measured mount's (feet above the camera teach nothing, below)."""
    measured = []                                           # each frame's features, as the detector measured them
    measure = detector_module.measure
    monkeypatch.setattr(detector_module, "measure", lambda *a, **k: measured.append(measure(*a, **k)) or measured[-1])
    seated_calls = []
    observe_floor = CameraGeometry.observe_floor

    def spy(self, *args, **kwargs):
        if not measured[-1].upright_legs:                   # a seated frame's feet
            seated_calls.append(self.measured)
        return observe_floor(self, *args, **kwargs)

    monkeypatch.setattr(CameraGeometry, "observe_floor", spy)
    sc = WALL["wall/tune/fall/sitting-sideways/fast-v30"]
    for cfg in (FallsConfig(), FallsConfig(camera_tilt_deg=35.0, camera_height_m=2.0)):
        run(sc, cfg)
    assert False in seated_calls and True in seated_calls   # under the guess and on the measured mount


def test_a_floor_not_yet_learned_gives_way_to_the_bodies_seen_when_the_guess_is_rejected():
    """Two seated frames' feet under the level guess are no floor yet (``FLOOR_MIN_WEIGHT`` observations make
    one). When the body then rejects the guess, the floor comes from every straight and seated body seen so far
    (their feet, as points), not from those two: before, it stayed unknown and the lowest fitted joint stood in,
    so a person lying back on a sofa read as on the floor (the orthographic fit, wall camera, default config)."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    ahead = np.array([0.0, -np.sin(tilt), np.cos(tilt)])
    ankle_height = 0.08
    ankles = 1.5 * ahead + (2.0 - ankle_height) * down            # the floor 2 m below the camera
    geo = CameraGeometry(FallsConfig())
    for _ in range(2):
        geo.observe_floor(float(ankles[1]) + ankle_height, ankles, ankle_height)   # along the level guess
    assert geo.used()["floor"] == "config" and geo.state()["floor"]["weight"] == 2.0
    for _ in range(30):
        geo.observe_body_axis(-down, 0.1, ankles, ankle_height)
    assert geo.used() == {"gravity": "body", "floor": "learned", "config": "guess"}
    assert geo.floor_below_camera == pytest.approx(2.0, abs=0.15)


def test_feet_above_the_camera_teach_no_floor():
    """Along a gravity 20 deg or more off (a tilt left at 0 on a camera looking down), feet a few metres away
    come out above the camera: no floor is there, and learning one put everyone at floor level (a person
    sitting down on a chair raised a fall). Such observations are dropped; real ones are learned."""
    geo = CameraGeometry(FallsConfig(camera_height_m=1.3))
    for _ in range(10):
        geo.observe_floor(-0.47)
    assert geo.floor_below_camera == 1.3 and geo.used()["floor"] == "config"
    for _ in range(5):
        geo.observe_floor(1.1)
    assert geo.floor_below_camera == pytest.approx(1.1) and geo.used()["floor"] == "learned"


def test_a_floor_point_above_the_camera_is_not_taken_when_the_body_rejects_the_guess():
    """The feet seen under the level guess keep a point on the floor; when the standing body rejects the guess
    that point is re-projected along the body's gravity. A point that comes out at or above the camera there (a
    fit gone wrong: feet read 0.3 m above the lens) is no floor, as :meth:`CameraGeometry.observe_floor` says
    of feet above the camera: heights fall back to the lowest joint instead of a floor above the person."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    ahead = np.array([0.0, -np.sin(tilt), np.cos(tilt)])
    ankle_height = 0.08
    geo = CameraGeometry(FallsConfig())
    for _ in range(30):                                           # 3 s standing at 10 fps
        geo.observe_body_axis(-down, 0.1, 3.0 * ahead - 0.3 * down, ankle_height)
    assert geo.used()["gravity"] == "body"
    assert geo.floor_below_camera is None and geo.used()["floor"] == "lowest_joint"
    # the same body over feet 2 m below the camera: that floor is taken
    good = CameraGeometry(FallsConfig())
    for _ in range(30):
        good.observe_body_axis(-down, 0.1, 3.0 * ahead + (2.0 - ankle_height) * down, ankle_height)
    assert good.used()["floor"] == "learned" and good.floor_below_camera == pytest.approx(2.0, abs=0.15)


def _standing(geo: CameraGeometry, down_read: np.ndarray, ankles: np.ndarray, ankle_height: float, s: float) -> None:
    for _ in range(round(s / 0.1)):                               # standing, 10 fps
        geo.observe_body_axis(-down_read, 0.1, ankles, ankle_height)


def test_feet_above_the_camera_along_the_guess_reject_it():
    """A robot's camera 1.3 m up and 22 deg down, the config told nothing, a person standing 4.4 m away. The
    fit's body axis reads the tilt as 11 deg (its depth is poor): within BODY_REJECT_DEG of the level guess,
    which the angle alone keeps. But along the level guess the person's feet come out above the camera, where
    no camera above the floor sees the feet of someone on that floor: the guess is rejected all the same,
    gravity comes from the body and the floor from under the feet (before, the guess stayed, no floor was
    learned from feet "above the camera", and falls there lay at 0.6-0.8 of a standing pelvis height)."""
    def down_at(deg: float) -> np.ndarray:
        return np.array([0.0, np.cos(np.radians(deg)), np.sin(np.radians(deg))])

    ahead = np.array([0.0, -np.sin(np.radians(22.0)), np.cos(np.radians(22.0))])   # level, away from the camera
    ankle_height = 0.07
    ankles = 4.4 * ahead + (1.3 - ankle_height) * down_at(22.0)
    assert ankles[1] < 0.0                                       # above the camera along the level guess
    geo = CameraGeometry(FallsConfig())
    _standing(geo, down_at(11.0), ankles, ankle_height, 0.5)
    assert geo.used()["gravity"] == "config"                     # not before BODY_MIN_S of them
    _standing(geo, down_at(11.0), ankles, ankle_height, 1.0)
    assert geo.used() == {"gravity": "body", "floor": "learned", "config": "guess"}
    assert geo.summary()["tilt_deg"] == pytest.approx(11.0, abs=0.5)
    assert geo.floor_below_camera > 0.0                          # the feet are below the camera along it
    # the same body axis over feet below the camera (a camera 12 deg down, the person 2 m away): kept
    near = 2.0 * np.array([0.0, -np.sin(np.radians(12.0)), np.cos(np.radians(12.0))]) \
        + (1.0 - ankle_height) * down_at(12.0)
    assert near[1] > 0.0
    kept = CameraGeometry(FallsConfig())
    _standing(kept, down_at(11.0), near, ankle_height, 3.0)
    assert kept.used()["gravity"] == "config" and kept.floor_below_camera == pytest.approx(1.0)


def test_a_standing_height_measured_along_a_rejected_guess_is_forgotten():
    """The standing pelvis height learned along the level guess, above its 1 m floor, is no measurement once the
    body rejects the guess: kept, it made a person sitting back on a sofa read as lying on the floor (a robot's
    camera 18 deg down, the default config). Refining the body's gravity afterwards keeps what was learned."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    ahead = np.array([0.0, -np.sin(tilt), np.cos(tilt)])
    ankle_height = 0.08
    geo = CameraGeometry(FallsConfig())
    for _ in range(5):
        geo.observe_standing_pelvis(2.4)                          # along the guess: far above its floor
    assert geo.standing_pelvis() == pytest.approx(2.4)
    _standing(geo, down, 3.0 * ahead + (2.0 - ankle_height) * down, ankle_height, 3.0)
    assert geo.used()["gravity"] == "body" and geo.standing_pelvis() is None
    for _ in range(5):
        geo.observe_standing_pelvis(0.9)
    tilted = np.array([0.0, np.cos(tilt + 0.1), np.sin(tilt + 0.1)])   # the body's gravity refined by 5.7 deg
    _standing(geo, tilted, 3.0 * ahead + (2.0 - ankle_height) * down, ankle_height, 30.0)
    assert geo.summary()["tilt_deg"] > 37.0 and geo.standing_pelvis() == pytest.approx(0.9)



def test_a_body_tipping_over_does_not_refine_the_gravity_it_rejected_the_guess_with():
    """A fall's first half second is a straight body too (a person toppling like a plank). Once the standing
    body has rejected the guess, such a body further than ``upright_trunk_deg`` from the gravity in use is no
    evidence of gravity: before, the traced wall-camera fall (standing, sideways) pulled the body's tilt from
    33 to 31 deg while tipping over, the motion was forgotten and the person read above lying height."""
    tilt = np.radians(35.0)
    down = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    geo = CameraGeometry(FallsConfig())
    for _ in range(20):                                           # 2 s standing: the level guess is rejected
        geo.observe_body_axis(-down, 0.1)
    assert geo.used()["gravity"] == "body"
    g0 = geo.gravity.copy()
    for deg in range(25, 45, 2):                                  # toppling towards the camera, 25-43 deg
        a = np.radians(-deg)
        rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        assert not geo.observe_body_axis(-(rot @ down), 0.1)
    assert np.allclose(geo.gravity, g0)
    for _ in range(5):                                            # standing again, 10 deg of sway: still evidence
        a = np.radians(10.0)
        rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        geo.observe_body_axis(-(rot @ down), 0.1)
    assert geo._body_s == pytest.approx(2.5)
