"""``posed bench falls --extractor holistic``: the scenarios' landmarks as MediaPipe Holistic gives them on the
real urfd_dev recordings (bench/falls_extractor.py)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls import scenario_cases
from posed.bench.falls_extractor import (
    HOLISTIC_KEPT,
    LOST_AFTER_S,
    LOST_SHARE,
    WRIST_RUN_S,
    WRIST_SHARE,
    _wrist_chain,
    as_extractor,
)
from posed.cli import main


@pytest.fixture(scope="module")
def tune_cases():
    return scenario_cases("tune")


def test_blazepose_leaves_the_case_as_it_is(tune_cases):
    case = tune_cases[0]
    assert as_extractor(case, "blazepose") is case
    with pytest.raises(ValueError, match="blazepose, holistic"):
        as_extractor(case, "openpose")


def test_holistic_keeps_the_body_landmarks_drops_the_elbows_and_shows_the_wrists_sometimes(tune_cases):
    case = next(c for c in tune_cases if c.kind == "adl")
    out = as_extractor(case, "holistic")
    assert len(out.frames) == len(case.frames)
    wrist_frames = 0
    for before, after in zip(case.frames, out.frames, strict=True):
        assert (before.landmarks is None) == (after.landmarks is None)     # a daily activity is never lost
        if after.landmarks is None:
            continue
        shown = ~np.isnan(after.landmarks).any(axis=1)
        assert shown[list(HOLISTIC_KEPT)].all()
        np.testing.assert_array_equal(after.landmarks[list(HOLISTIC_KEPT)], before.landmarks[list(HOLISTIC_KEPT)])
        assert not shown[[13, 14]].any()                                   # elbows
        assert not shown[[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]].any()            # the face but the nose
        assert not shown[[17, 18, 19, 20, 21, 22, 29, 30, 31, 32]].any()   # hands and feet
        wrist_frames += int(shown[15]) + int(shown[16])
        assert set(np.flatnonzero(shown)) <= set(HOLISTIC_KEPT) | {15, 16}
    # seeded by the case's name: the same landmarks every run
    again = as_extractor(case, "holistic")
    assert all(np.array_equal(a.landmarks, b.landmarks, equal_nan=True)
               for a, b in zip(out.frames, again.frames, strict=True) if a.landmarks is not None)
    assert wrist_frames < len(case.frames)       # 2 wrists: far under the 2 per frame BlazePose gives


def test_the_wrist_chain_has_urfd_dev_s_share_and_run_length():
    shown = _wrist_chain(200_000, 30.0, np.random.default_rng(5))
    share = shown.mean()
    edges = np.flatnonzero(np.diff(shown.astype(int)) == -1)
    starts = np.flatnonzero(np.diff(shown.astype(int)) == 1)
    runs = shown.sum() / max(len(edges), len(starts))
    assert share == pytest.approx(WRIST_SHARE, rel=0.1)
    assert runs == pytest.approx(WRIST_RUN_S * 30.0, rel=0.1)
    assert not _wrist_chain(100, 10.0, np.random.default_rng(1)).all()


def test_falls_lose_the_person_after_the_impact_in_urfd_dev_s_share(tune_cases):
    falls = [c for c in tune_cases + scenario_cases("heldout") if c.kind == "fall"]
    lost = 0
    for case in falls:
        out = as_extractor(case, "holistic")
        gone = [fr.t for fr, before in zip(out.frames, case.frames, strict=True)
                if fr.landmarks is None and before.landmarks is not None]
        if not case.truth.seen_falling:
            assert gone == []                       # found lying: nobody would be in the recording
            continue
        if not gone:
            continue
        lost += 1
        first = min(gone)
        dt = 1.0 / 10.0
        assert LOST_AFTER_S[0] <= first - case.truth.t_impact <= LOST_AFTER_S[1] + dt
        # lost for good: every frame from the first lost one on
        assert gone == [fr.t for fr in case.frames if fr.t >= first and fr.landmarks is not None]
    seen_falling = sum(c.truth.seen_falling for c in falls)
    assert 0.2 * seen_falling <= lost <= 0.55 * seen_falling
    assert abs(lost / seen_falling - LOST_SHARE) < 0.15


def test_a_fall_lost_after_the_impact_keeps_every_frame_before_it(tune_cases):
    case = next(c for c in tune_cases if c.name == "tune/fall/standing-forward/fast-v100")
    for seed_name in (f"probe-{k}" for k in range(40)):    # find a name whose draw loses the person
        renamed = replace(case, name=seed_name)
        out = as_extractor(renamed, "holistic")
        if out.frames[-1].landmarks is None:
            break
    else:
        pytest.fail("no draw of 40 lost the person: the share is far under urfd_dev's 3 of 8")
    before_impact = [fr for fr in out.frames if fr.t <= case.truth.t_impact]
    assert all(fr.landmarks is not None for fr in before_impact)


def test_the_bench_runs_the_holistic_landmarks_and_says_so(capsys):
    code = main(["bench", "falls", "--truth", "--split", "tune", "--only", "fall/standing-sideways/fast",
                 "--extractor", "holistic", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert report["extractor"]["name"] == "holistic" and "urfd_dev" in report["extractor"]["meaning"]
    assert len(report["scenarios"]) == 2 and report["recall"] == 1.0 and code == 0
    main(["bench", "falls", "--truth", "--split", "tune", "--only", "fall/standing-sideways/fast", "--json"])
    assert json.loads(capsys.readouterr().out)["extractor"]["name"] == "blazepose"


def test_world_landmarks_cannot_go_with_another_extractor(capsys):
    code = main(["bench", "falls", "--split", "tune", "--only", "nothing", "--world", "--extractor", "holistic"])
    err = capsys.readouterr().err
    assert code == 2 and "--world" in err and "holistic" in err
    from posed.bench.falls import run_bench
    with pytest.raises(ValueError, match="drop one of them"):
        run_bench(["tune"], "truth", only="nothing", world=True, extractor="holistic")
