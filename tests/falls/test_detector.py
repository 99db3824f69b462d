"""The fall detector on scripted sequences (perfect fits of the simulated body: the detector alone).

The benchmark (`posed bench falls`) runs the same scenarios through the real fit; here every scenario class
of the tuning split runs with ground-truth joints so that each test is fast and its failure names the class.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls_body import StickPose
from posed.bench.falls_scenarios import (
    SIT,
    STAND,
    Key,
    Scenario,
    Truth,
    catalogue,
    fall_from_standing,
    frames,
    make,
    truth_result,
)
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.event import FallEvent
from posed.falls.features import gravity_from_tilt

TUNE = {sc.name: sc for sc in catalogue("tune")}


def run(sc: Scenario, cfg: FallsConfig | None = None, ids=None, gravity=None) -> list[FallEvent]:
    cfg = cfg or FallsConfig()
    cfg = replace(cfg, camera_tilt_deg=sc.camera.tilt, camera_height_m=sc.camera.z)
    counter = itertools.count()
    det = FallDetector(cfg, "r1", fit_frame="camera", id_factory=ids or (lambda: f"ev{next(counter)}"))
    if gravity is not None:
        det.set_gravity(gravity)
    out = []
    for fr in frames(sc):
        out += det.update(truth_result(fr, sc.camera), fr.landmarks, (sc.camera.width, sc.camera.height),
                          intrinsics=sc.camera.intrinsics)
    return out


@pytest.mark.parametrize("name", sorted(TUNE))
def test_scenario(name):
    sc = TUNE[name]
    events = run(sc)
    first = next((e for e in events if e.state in ("falling", "on_floor")), None)
    if sc.kind == "adl":
        assert events == [], f"false alarm: {[e.state for e in events]}"
        return
    assert first is not None, "fall not detected"
    latency = first.t_detect - sc.truth.t_impact
    assert -0.2 <= latency <= 1.5, latency
    assert first.robot == "r1" and 0.5 <= first.confidence <= 0.99 and first.features
    assert first.pose is not None and first.pose["ok"] is True
    if sc.truth.seen_falling:
        assert first.t_onset is not None and first.t_onset <= first.t_impact <= first.t_detect
    assert len({e.id for e in events}) == 1, "one fall, one event id"
    assert FallEvent.from_json(first.to_json()) == first


def long_fall(after: float, get_up: bool, seed: int = 3, dropouts=()) -> Scenario:
    keys, truth = fall_from_standing("sideways", 1.0, 1.0, after=after)
    if get_up:
        t = keys[-1].t
        keys = keys + [Key(t + 1.0, SIT.with_(pitch=-10, hip_flex_l=80, hip_flex_r=80, knee_l=70, knee_r=70)),
                       Key(t + 2.0, StickPose(knee_l=90, knee_r=90, hip_flex_l=10, hip_flex_r=60, trunk_flex=10)),
                       Key(t + 3.0, STAND), Key(t + 6.0, STAND, ease="hold")]
    return make("long-fall", "fall", (keys, truth), 30.0, 3.0, 1.0, 12.0, seed, dropouts=dropouts)


def test_alarm_after_configured_time_then_recovered():
    sc = long_fall(after=5.0, get_up=True)
    events = run(sc, FallsConfig(alarm_after_s=3.0))
    states = [e.state for e in events]
    assert states == ["falling", "on_floor", "alarm", "recovered"]
    assert len({e.id for e in events}) == 1
    alarm = events[2]
    assert alarm.t_impact is not None and 3.0 <= alarm.t_detect - alarm.t_impact <= 3.0 + 1 / sc.fps + 1e-9
    assert "not_recovered" in alarm.features
    assert events[3].t_detect > sc.truth.t_impact + 5.0


def test_getting_up_before_the_alarm_time_raises_no_alarm():
    events = run(long_fall(after=2.0, get_up=True), FallsConfig(alarm_after_s=8.0))
    assert [e.state for e in events] == ["falling", "on_floor", "recovered"]


def test_losing_sight_after_a_fall_does_not_hide_the_alarm():
    sc = long_fall(after=6.0, get_up=False)
    sc.dropouts = ((sc.truth.t_impact + 1.5, 99.0),)   # the person is never seen again
    events = run(sc, FallsConfig(alarm_after_s=4.0))
    assert [e.state for e in events] == ["falling", "on_floor", "alarm"]


def test_a_few_lost_frames_neither_cause_nor_hide():
    standing = make("stand", "adl", ([Key(0.0, STAND), Key(6.0, STAND, ease="hold")], Truth("adl")),
                    0.0, 3.0, 1.0, 12.0, 5, dropouts=((1.0, 1.4), (2.0, 2.3), (4.0, 4.5)))
    assert run(standing) == []
    sc = long_fall(after=3.0, get_up=False)
    ti = sc.truth.t_impact
    sc.dropouts = ((ti - 0.3, ti + 0.2), (ti + 1.0, ti + 1.3))
    events = run(sc)
    assert events and events[0].state in ("falling", "on_floor")
    assert events[0].t_detect - ti <= 1.5


def test_replay_gives_the_same_events():
    sc = TUNE["tune/fall/standing-forward/fast-v30"]
    a, b = run(sc), run(sc)
    assert a == b and a


def test_single_bad_frame_is_ignored():
    sc = make("stand", "adl", ([Key(0.0, STAND), Key(5.0, STAND, ease="hold")], Truth("adl")), 0.0, 3.0, 1.0, 12.0,
              9)
    lying = TUNE["tune/fall/found-lying-sideways/v30"]
    bad = next(f for f in frames(lying) if f.seq == 10)
    det = FallDetector(replace(FallsConfig(), camera_tilt_deg=12.0, camera_height_m=1.0), "r1", fit_frame="camera")
    out = []
    for fr in frames(sc):
        src = (bad, lying.camera) if fr.seq == 25 else (fr, sc.camera)
        res = replace(truth_result(*src), seq=fr.seq, t=fr.t)
        out += det.update(res, src[0].landmarks, (640, 480), intrinsics=sc.camera.intrinsics)
    assert out == []


def test_torso_out_of_view_is_not_judged():
    """Three of the four torso landmarks are a partial body that is judged; two missing are not."""
    sc = TUNE["tune/fall/found-lying-backward/v30"]
    fr = next(iter(frames(sc)))
    lm = fr.landmarks.copy()
    det = FallDetector(replace(FallsConfig(), camera_tilt_deg=sc.camera.tilt, camera_height_m=sc.camera.z), "r",
                       fit_frame="camera")
    res = truth_result(fr, sc.camera)
    lm_out = lm.copy()
    lm_out[23, 1] = 10_000.0                    # the left hip below the image
    lm_out[11, 1] = 10_000.0                    # and the left shoulder
    det.update(res, lm_out, (640, 480), intrinsics=sc.camera.intrinsics)
    assert det.last_sample is None
    lm_hidden = lm.copy()
    lm_hidden[12, 3] = 0.1                      # the right shoulder not visible
    lm_hidden[24, 3] = 0.1                      # nor the right hip
    det.update(res, lm_hidden, (640, 480), intrinsics=sc.camera.intrinsics)
    assert det.last_sample is None
    det.update(res, lm, (640, 480), intrinsics=sc.camera.intrinsics)
    assert det.last_sample is not None and det.last_sample.incl > 60


def test_unknown_intrinsics_fall_back_to_the_field_of_view():
    from posed.camera_model import Intrinsics

    sc = TUNE["tune/fall/standing-backward/fast-v30"]
    assert sc.camera.intrinsics == Intrinsics.from_hfov(sc.camera.hfov, 640, 480)
    cfg = replace(FallsConfig(camera_hfov_deg=sc.camera.hfov), camera_tilt_deg=sc.camera.tilt,
                  camera_height_m=sc.camera.z)
    with_k, without = (FallDetector(cfg, "r1", fit_frame="camera", id_factory=lambda: "ev") for _ in range(2))
    a, b = [], []
    for fr in frames(sc):
        res = truth_result(fr, sc.camera)
        a += [(e.state, e.t_detect) for e in with_k.update(res, fr.landmarks, (640, 480), sc.camera.intrinsics)]
        b += [(e.state, e.t_detect) for e in without.update(res, fr.landmarks, (640, 480), None)]
    assert a == b and a


def test_imu_gravity_equals_configured_tilt():
    sc = TUNE["tune/fall/standing-backward/fast-v30"]
    with_imu = run(sc, FallsConfig(camera_tilt_deg=0.0), gravity=gravity_from_tilt(sc.camera.tilt) * 9.81)
    assert [(e.state, e.t_detect) for e in with_imu] == [(e.state, e.t_detect) for e in run(sc)]
    g = gravity_from_tilt(90.0)
    np.testing.assert_allclose(g, [0.0, 0.0, 1.0], atol=1e-12)   # looking straight down: gravity along +z


@pytest.mark.parametrize("name", ["tune/fall/standing-backward/fast-v30", "tune/fall/sitting-sideways/slow-v100",
                                  "tune/adl/sit-down-chair/normal-v30", "tune/adl/lie-on-bed-side/quick-v100"])
def test_imu_readings_that_move_every_frame_keep_the_motion(name):
    """An accelerometer's gravity that jitters by 1 degree rms from frame to frame (a robot driving, a
    vibrating head) with a wrong configured tilt (0): each reading is used as it comes and the motion is not
    forgotten, so falls are caught as with the true tilt configured, and daily activities stay quiet."""
    sc = TUNE[name]
    det = FallDetector(FallsConfig(camera_tilt_deg=0.0, camera_height_m=sc.camera.z), "r1", fit_frame="camera",
                       id_factory=lambda: "ev")
    rng = np.random.default_rng(11)
    true_g = gravity_from_tilt(sc.camera.tilt, sc.camera.roll)
    events = []
    for fr in frames(sc):
        e = rng.normal(0.0, np.radians(1.0), 2)
        g = true_g + e[0] * np.cross(true_g, [1.0, 0.0, 0.0]) + e[1] * np.cross(true_g, [0.0, 0.0, 1.0])
        det.set_gravity(9.81 * g / np.linalg.norm(g))
        events += det.update(truth_result(fr, sc.camera), fr.landmarks, (sc.camera.width, sc.camera.height),
                             intrinsics=sc.camera.intrinsics)
    assert det.geometry["tilt_from"] == "imu"
    want = run(sc)
    assert [e.state for e in events] == [e.state for e in want]
    for got, ref in zip(events, want, strict=True):
        assert abs(got.t_detect - ref.t_detect) <= 0.5     # 1 degree moves a pelvis 3 m away by ~5 cm


def test_disabled_floor_knowledge_falls_back_to_body_geometry():
    sc = TUNE["tune/fall/found-lying-backward/v30"]
    det = FallDetector(FallsConfig(camera_height_m=0.0, learn_floor=False, camera_tilt_deg=sc.camera.tilt), "r",
                       fit_frame="camera")
    states = []
    for fr in frames(sc):
        states += [e.state for e in det.update(truth_result(fr, sc.camera), fr.landmarks, (640, 480),
                                               intrinsics=sc.camera.intrinsics)]
    assert states == ["on_floor"]
