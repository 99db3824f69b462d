"""Several people, a fall detector each (falls.people.PeopleFalls), on ground-truth fits of the simulated bodies
so that the per-person logic is tested alone (the real fit: ``posed bench people``, falls with a bystander).

What must hold: a fall of someone who is not the frame's own person is seen; a bystander standing, walking or
kneeling beside the person who fell neither ends the event nor raises one; a person lost at the impact while
someone else stays in view is still judged on the descent and their alarm still comes; re-found under a new
track id, they keep their event (``person_match``); the one person of a stream without ids gets exactly the
messages of a single detector.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from posed.bench import people_falls as pf
from posed.bench.falls_scenarios import STAND, Key, Truth, catalogue, frames, make, truth_result
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.people import PeopleFalls
from posed.fitting import FitResult

HELDOUT = {sc.name: sc for sc in catalogue("heldout")}
FALL = "heldout/fall/standing-sideways/fast-v150"
OCCLUDED = "heldout/fall/occluded-at-impact/v150"


def cfg_for(sc, **kw) -> FallsConfig:
    return replace(FallsConfig(), camera_tilt_deg=sc.camera.tilt, camera_height_m=sc.camera.z,
                   camera_geometry="measured", **kw)


def ids():
    counter = itertools.count()
    return lambda: f"ev{next(counter)}"


def detector(cfg) -> FallDetector:
    return FallDetector(cfg, "r1", fit_frame="camera", id_factory=ids())


@pytest.mark.parametrize("kind", pf.BYSTANDERS)
def test_a_bystander_neither_hides_the_fall_nor_raises_one(kind):
    case = pf.with_bystander(HELDOUT[FALL], kind)
    row = pf.run_case(case, pf._fitter_factory("truth"), cfg_for(case.faller))
    assert row["detected"], row["states"]
    assert row["bystander_events"] == 0 and row["event_ids"] == 1 and not row["ended"], row["states"]
    assert row["switches"] == {"faller": 0, "bystander": 0}


def test_a_kneeling_bystander_does_not_end_the_event_of_someone_found_lying():
    name = next(n for n in HELDOUT if "found-lying" in n)
    case = pf.with_bystander(HELDOUT[name], "kneeling")
    row = pf.run_case(case, pf._fitter_factory("truth"), cfg_for(case.faller))
    assert row["detected"] and row["event_ids"] == 1 and not row["ended"] and row["bystander_events"] == 0


def test_a_daily_activity_with_a_kneeling_bystander_raises_nothing():
    name = next(n for n in HELDOUT if "/adl/sit-down-chair/" in n)
    case = pf.with_bystander(HELDOUT[name], "kneeling")
    row = pf.run_case(case, pf._fitter_factory("truth"), cfg_for(case.faller))
    assert row["states"] == []


def two_streams(faller_sc, other_xy=(1.5, 3.3), faller_id=2, other_id=1, lose_after=None, refind_at=None,
                refind_id=9, cfg=None):
    """Run a fall (track ``faller_id``) with a person standing at ``other_xy`` (``other_id``, followed longer:
    the frame's own person) through PeopleFalls; the faller lost from ``lose_after`` and re-found under
    ``refind_id`` from ``refind_at``."""
    cam = faller_sc.camera
    stand = make("stand", "adl", ([Key(0.0, STAND, xy=other_xy), Key(faller_sc.duration, STAND, xy=other_xy,
                                                                      ease="hold")], Truth("adl")),
                 0.0, 3.0, cam.z, cam.tilt, seed=5, start_xy=other_xy)
    cfg = cfg or cfg_for(faller_sc)
    watch = PeopleFalls(detector(cfg), lambda: detector(cfg))
    out = []
    for a, b in zip(frames(faller_sc), frames(stand), strict=False):
        people = [(other_id, truth_result(b, cam), b.landmarks)]
        lm = a.landmarks
        fid = faller_id
        if lose_after is not None and a.t >= lose_after and (refind_at is None or a.t < refind_at):
            lm = None
        if refind_at is not None and a.t >= refind_at:
            fid = refind_id
        if lm is not None:
            r = truth_result(a, cam)
            r = replace(r, extra={**r.extra, "person": fid, "root_cam_m": [0.1, 0.2, 3.0]})
            people.append((fid, r, lm))
        out += watch.update(people, a.t, a.seq, (cam.width, cam.height), cam.intrinsics)
    return out, watch


def test_the_fall_of_a_person_who_is_not_the_frames_own_is_seen_and_says_whose_it_is():
    events, watch = two_streams(HELDOUT[FALL])
    assert events and {e.extra["person"] for e in events} == {2}
    assert events[0].state == "falling" and events[0].extra["root_cam_m"] == [0.1, 0.2, 3.0]
    assert watch.main_key == 1 and watch.people[2].detector.state == "down"
    assert watch.people[1].detector.state == "up"


def test_lost_at_the_impact_beside_someone_in_view_is_judged_on_the_descent_and_the_alarm_comes():
    sc = HELDOUT[FALL]
    events, _ = two_streams(sc, lose_after=sc.truth.t_impact + 0.1, cfg=cfg_for(sc, alarm_after_s=3.0))
    states = [e.state for e in events]
    assert states[0] == "falling" and "lost_after_descent" in events[0].features
    assert "alarm" in states and "recovered" not in states
    assert len({e.id for e in events}) == 1


def test_refound_under_a_new_id_the_person_keeps_their_event():
    sc = HELDOUT[FALL]
    t_imp = sc.truth.t_impact
    events, watch = two_streams(sc, lose_after=t_imp + 0.1, refind_at=t_imp + 2.5)
    assert len({e.id for e in events}) == 1, [(e.state, e.extra.get("person")) for e in events]
    assert watch.rematches == 1 and 9 in watch.people and 2 not in watch.people
    assert watch.people[9].detector.state == "down"
    later = [e for e in events if e.extra["person"] == 9]
    assert all(e.extra["person_match"]["previous"] == 2 and 0 < e.extra["person_match"]["sure"] <= 1 for e in later)


def test_a_new_id_far_from_where_someone_was_lost_is_someone_else():
    sc = HELDOUT[FALL]
    watch = PeopleFalls(detector(cfg_for(sc)))
    cam = sc.camera
    fr = list(frames(sc))
    lm_near = fr[0].landmarks
    lm_far = lm_near.copy()
    lm_far[:, 0] += 0.6 * cam.width * 0.5           # half the image across
    size = (cam.width, cam.height)
    watch.update([(1, truth_result(fr[0], cam), lm_near)], 0.0, 0, size, cam.intrinsics)
    watch.update([(None, FitResult.failure(1, 3.0, "no person"), None)], 3.0, 1, size, cam.intrinsics)
    watch.update([(5, truth_result(fr[1], cam), lm_far)], 3.1, 2, size, cam.intrinsics)
    assert watch.rematches == 0 and set(watch.people) == {1, 5}


def test_one_person_without_ids_gets_exactly_a_single_detectors_messages():
    sc = HELDOUT[OCCLUDED]
    cfg = cfg_for(sc)
    alone, people = detector(cfg), PeopleFalls(detector(cfg))
    size = (sc.camera.width, sc.camera.height)
    a_out, p_out = [], []
    for fr in frames(sc):
        r = truth_result(fr, sc.camera)
        a_out += alone.update(r, fr.landmarks, size, sc.camera.intrinsics)
        p_out += people.update([(None, r, fr.landmarks)], fr.t, fr.seq, size, sc.camera.intrinsics)
    assert a_out and [e.to_json() for e in a_out] == [e.to_json() for e in p_out]
    assert all("person" not in e.extra for e in p_out)


def test_a_carer_entering_after_an_unseen_fall_gets_a_detector_of_their_own():
    """One person, no ids, falls and is lost at the impact; a carer then walks in (the first id): the carer
    is not the person who fell (they were not in view the frame before), the fallen one's alarm still comes."""
    sc = HELDOUT[FALL]
    cfg = cfg_for(sc, alarm_after_s=4.0)
    cam, size = sc.camera, (sc.camera.width, sc.camera.height)
    watch = PeopleFalls(detector(cfg), lambda: detector(cfg))
    out = []
    fr = list(frames(sc))
    carer = fr[0].landmarks.copy()
    carer[:, 0] = np.clip(carer[:, 0] + 0.45 * cam.width, 0, cam.width - 1)   # standing elsewhere
    t_lost = sc.truth.t_impact + 0.1
    for f in fr:
        if f.t < t_lost:
            out += watch.update([(None, truth_result(f, cam), f.landmarks)], f.t, f.seq, size, cam.intrinsics)
        elif f.t < t_lost + 1.0:
            out += watch.update([(None, FitResult.failure(f.seq, f.t, "no person"), None)], f.t, f.seq, size,
                                cam.intrinsics)
        else:
            r = truth_result(replace(fr[0], seq=f.seq, t=f.t), cam)
            out += watch.update([(1, replace(r, extra={"person": 1}), carer)], f.t, f.seq, size, cam.intrinsics)
    for k in range(30):                                 # the carer stands on; time passes
        t = fr[-1].t + 0.1 * (k + 1)
        r = truth_result(replace(fr[0], seq=fr[-1].seq + k + 1, t=t), cam)
        out += watch.update([(1, replace(r, extra={"person": 1}), carer)], t, fr[-1].seq + k + 1, size,
                            cam.intrinsics)
    states = [e.state for e in out]
    assert states[0] == "falling" and "alarm" in states and "recovered" not in states, states
    assert all("person" not in e.extra for e in out)     # the one person of the stream without ids
    assert watch.main_key == 1 and None in watch.people and watch.people[None].detector.state == "alarm"
