"""Who is who: stature by ground-plane metrology (falls.stature) and the household's recognition
(falls.household), alone and in PeopleFalls, on bodies of known height rendered through known cameras."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls_body import Body
from posed.bench.falls_scenarios import STAND, Key, Truth, catalogue, frames, make, truth_result, walk
from posed.falls.config import FallsConfig, HouseholdMember
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt
from posed.falls.household import MIN_SAMPLES, TOLERANCE_M, Household
from posed.falls.people import PeopleFalls
from posed.falls.stature import stature_m


def standing(height: float, dist: float, cam_z: float, tilt: float, xy=None, seconds: float = 3.0, seed: int = 3):
    sc = make("s", "adl", ([Key(0.0, STAND, xy=xy), Key(seconds, STAND, xy=xy, ease="hold")], Truth("adl")),
              30.0, dist, cam_z, tilt, seed=seed, start_xy=xy)
    return replace(sc, body=Body(height))


@pytest.mark.parametrize("height", [1.52, 1.65, 1.83])
@pytest.mark.parametrize("dist,cam_z,tilt", [(2.6, 0.9, 8.0), (3.0, 1.0, 12.0), (4.4, 1.3, 22.0)])
def test_stature_from_one_image_matches_the_body(height, dist, cam_z, tilt):
    sc = standing(height, dist, cam_z, tilt)
    d = gravity_from_tilt(tilt, 0.0)
    got = [stature_m(f.landmarks, sc.camera.intrinsics, d, cam_z) for f in frames(sc)]
    got = [g for g in got if g is not None]
    assert len(got) >= 20
    assert abs(float(np.median(got)) - height) < 0.02


def test_stature_is_refused_without_what_it_needs():
    sc = standing(1.65, 3.0, 1.0, 12.0)
    lm = next(iter(frames(sc))).landmarks
    d, cam = gravity_from_tilt(12.0, 0.0), sc.camera.intrinsics
    assert stature_m(lm, cam, d, 0.0) is None                      # floor unknown
    hidden = lm.copy()
    hidden[27, 3] = 0.1                                            # an ankle not seen
    assert stature_m(hidden, cam, d, 1.0) is None
    assert stature_m(lm, cam, gravity_from_tilt(-60.0, 0.0), 1.0) is None   # the ankles above the horizon
    # a wrong camera height scales the stature: 10 % higher, about 10 % taller
    assert stature_m(lm, cam, d, 1.1) == pytest.approx(1.1 * stature_m(lm, cam, d, 1.0), rel=0.03)


def test_household_members_visitors_and_the_undecided():
    hh = Household((HouseholdMember("Anna", 1.60), HouseholdMember("Ben", 1.80), HouseholdMember("Cleo", 1.66)))
    for _ in range(MIN_SAMPLES - 1):
        hh.observe(1, 1.59)
    assert hh.who(1)["member"] is None and not hh.who(1)["visitor"]          # not enough yet
    hh.observe(1, 1.59)
    assert hh.who(1)["member"] == "Anna" and 0.8 < hh.who(1)["sure"] < 0.9 and hh.rank(1) == 0
    for _ in range(MIN_SAMPLES):
        hh.observe(2, 1.79)
        hh.observe(3, 1.90 + TOLERANCE_M - 0.05)        # beyond everyone: 1.92 is 0.12 from Ben
        hh.observe(4, 1.63)                             # between Anna and Cleo: either could be her
    assert hh.who(2)["member"] == "Ben" and hh.rank(2) == 1 and hh.who(2)["sure"] > 0.8
    assert hh.who(3)["visitor"] and hh.who(3)["member"] is None
    assert hh.who(4)["member"] is None and not hh.who(4)["visitor"]
    hh.rename(2, 9)
    assert hh.who(9)["member"] == "Ben" and hh.who(2)["samples"] == 0


def ids():
    counter = itertools.count()
    return lambda: f"ev{next(counter)}"


def test_the_history_follows_the_member_and_her_fall_says_who_she_is():
    """Anna (1.62 m) falls while a visitor (1.80 m, in view first: the frame's own person) stands beside her:
    she is recognised from her standing frames before the fall, followed (not the visitor), and her events say
    her name; the visitor is known as one."""
    fall = next(sc for sc in catalogue("heldout") if sc.name == "heldout/fall/standing-sideways/fast-v150")
    anna = replace(fall, body=Body(1.62))
    cam = anna.camera
    visitor = replace(make("v", "adl", ([Key(0.0, STAND, xy=(1.4, 3.4)), Key(anna.duration, STAND, xy=(1.4, 3.4),
                                                                            ease="hold")], Truth("adl")),
                           0.0, 3.0, cam.z, cam.tilt, seed=9, start_xy=(1.4, 3.4)), body=Body(1.80))
    cfg = replace(FallsConfig(), camera_tilt_deg=cam.tilt, camera_height_m=cam.z, camera_geometry="measured",
                  household=(HouseholdMember("Anna", 1.62),))
    watch = PeopleFalls(FallDetector(cfg, "r1", fit_frame="camera", id_factory=ids()))
    events, followed = [], []
    size = (cam.width, cam.height)
    for a, v in zip(frames(anna), frames(visitor), strict=False):
        people = [(1, replace(truth_result(v, cam), extra={"person": 1}), v.landmarks),
                  (2, replace(truth_result(a, cam), extra={"person": 2}), a.landmarks)]
        events += watch.update(people, a.t, a.seq, size, cam.intrinsics)
        followed.append(watch.followed())
    assert watch.household.who(2)["member"] == "Anna"
    assert watch.household.who(1)["visitor"]
    assert events and all(e.extra["member"] == "Anna" and e.extra["person"] == 2 for e in events)
    recognised = next(i for i, f in enumerate(followed) if f == 2)
    assert recognised <= 15 and all(f == 2 for f in followed[recognised:])
    status = watch.household_status()
    assert status["members"] == ["Anna"] and status["stature"] == "measured" and status["followed"] == 2


def test_without_a_measured_floor_nobody_is_recognised_and_the_status_says_why():
    sc = standing(1.62, 3.0, 1.0, 12.0)
    cfg = replace(FallsConfig(), household=(HouseholdMember("Anna", 1.62),))    # the default mount: a guess
    watch = PeopleFalls(FallDetector(cfg, "r1", fit_frame="camera"))
    size = (sc.camera.width, sc.camera.height)
    for f in frames(sc):
        watch.update([(1, truth_result(f, sc.camera), f.landmarks)], f.t, f.seq, size, sc.camera.intrinsics)
    assert watch.household.who(1)["samples"] == 0 and "measured" in watch.household_status()["stature"]
    assert watch.followed() == 1                       # not known: the frame's own person, as without a household


def test_a_visitor_alone_is_not_followed():
    path = [(-1.5, 3.5), (1.5, 3.5)]
    sc = make("w", "adl", walk(path, speed=0.6), 0.0, 3.5, 1.0, 12.0, seed=4, start_xy=path[0])
    sc = replace(sc, body=Body(1.85))
    cfg = replace(FallsConfig(), camera_tilt_deg=12.0, camera_height_m=1.0, camera_geometry="measured",
                  household=(HouseholdMember("Anna", 1.58),))
    watch = PeopleFalls(FallDetector(cfg, "r1", fit_frame="camera"))
    size = (sc.camera.width, sc.camera.height)
    seen = []
    for f in frames(sc):
        watch.update([(3, truth_result(f, sc.camera), f.landmarks)], f.t, f.seq, size, sc.camera.intrinsics)
        seen.append(watch.followed())
    assert watch.household.who(3)["visitor"], watch.household.who(3)
    assert seen[-1] is False
