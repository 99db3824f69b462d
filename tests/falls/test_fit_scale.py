"""A height in true metres against a fit in its own metres (``CameraGeometry.fit_scale``): without depth the fit's
lengths follow the body height it assumes, and every distance it places the body at scales with them, so the
robot's height (or a configured, measured one) is put in the fit's metres by the ratio of the floor seen under
a standing person's feet to it. The depth floor is left as it is (the fit is metric there)."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.falls.camera_geometry import FLOOR_MIN_WEIGHT, CameraGeometry
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector
from posed.falls.features import gravity_from_tilt

DOWN = gravity_from_tilt(15.0)


def test_the_robots_height_is_put_in_the_fits_metres_once_the_feet_give_the_scale():
    """A fit 5 % small sees the floor under standing feet at 0.95 of the robot's 1.2 m: after FLOOR_MIN_WEIGHT
    such frames the floor in use is 1.14 m (the fit's metres), and the scale holds when the mast rises to 1.5 m."""
    geo = CameraGeometry(FallsConfig())
    geo.set_robot(DOWN, 1.2)
    for _ in range(3 * int(FLOOR_MIN_WEIGHT)):               # seated feet teach the floor, not the scale
        geo.observe_floor(0.8 * 1.2)
    assert geo.fit_scale() is None and geo.floor_below_camera == pytest.approx(1.2)
    for _ in range(int(FLOOR_MIN_WEIGHT)):
        assert geo.floor_below_camera == pytest.approx(1.2) and not geo.floor_scaled   # not yet known
        geo.observe_floor(0.95 * 1.2, standing=True)
    assert geo.fit_scale() == pytest.approx(0.95) and geo.floor_scaled
    assert geo.floor_below_camera == pytest.approx(0.95 * 1.2)
    assert geo.metric_floor() == pytest.approx(1.2)          # true metres, for metrology (falls.stature)
    assert geo.summary()["floor_below_camera_m"] == pytest.approx(1.2)   # shown as the robot gave it
    geo.set_robot(DOWN, 1.5)                                 # the mast moved: the fit's scale did not
    assert geo.floor_below_camera == pytest.approx(0.95 * 1.5)
    geo.set_robot(None)                                      # let go: learned against the robot's height
    assert geo.fit_scale() is None


def test_a_measured_configured_height_is_scaled_a_guess_and_the_depth_floor_are_not():
    measured = CameraGeometry(FallsConfig(camera_height_m=1.3, camera_geometry="measured", learn_floor=True))
    guess = CameraGeometry(FallsConfig())
    depth = CameraGeometry(FallsConfig(camera_height_m=1.3, camera_geometry="measured"))
    depth.set_depth_floor(gravity_from_tilt(0.0), 1.3)
    for geo in (measured, guess, depth):
        for _ in range(int(FLOOR_MIN_WEIGHT)):
            geo.observe_floor(1.2, standing=True)
    assert measured.fit_scale() == pytest.approx(1.2 / 1.3)
    assert guess.fit_scale() is None                          # 1 m guessed: no true metres to compare with
    assert depth.fit_scale() is None and depth.floor_below_camera == pytest.approx(1.3)   # untouched
    # the learned floor (the fit's metres already) still comes before the configured height; when it is
    # forgotten (another level), the scale learned from the same feet goes with it
    assert measured.floor_below_camera == pytest.approx(1.2)
    measured.forget_floor()
    assert measured.fit_scale() is None and measured.floor_below_camera == pytest.approx(1.3)


def _scaled(result, k: float):
    """The same fit with every length ``k`` times: a fit that assumed a body ``k`` times as tall."""
    if not result.ok:
        return result
    return replace(result, joints_3d={n: k * np.asarray(v, float) for n, v in result.joints_3d.items()})


def _judge(sc, k: float):
    counter = itertools.count()
    det = FallDetector(FallsConfig(), "r1", fit_frame="camera", id_factory=lambda: f"ev{next(counter)}")
    cam = sc.camera
    heights, events = [], []
    for fr in frames(sc):
        det.set_camera_mount(gravity_from_tilt(cam.tilt, cam.roll), cam.z)
        events += det.update(_scaled(truth_result(fr, cam), k), fr.landmarks, (cam.width, cam.height),
                             cam.intrinsics)
        if det.last_sample is not None and det.camera.floor_scaled:   # from when the scale is known
            heights.append((det.last_sample.t, det.last_sample.h_rel))
    return det, heights, [(e.state, round(e.t_detect, 6)) for e in events]


@pytest.mark.parametrize("name", ["tune/fall/standing-forward/fast-v30", "tune/fall/collapse/slow-v100"])
def test_with_the_robots_height_a_fit_of_another_body_size_judges_the_same(name):
    """The body's pixels pin only the ratio of its size to its distance: a fit that assumes a body 1.6 / 1.65 as
    tall places every joint that much nearer the camera (pinhole: the same pixels), so every height below the
    camera is that much smaller, exactly. Heights relative to the standing pelvis measured against a floor in the
    same metres are then the same numbers; against the robot's true metres they were not (a lying pelvis read
    higher). So, frame by frame once the scale is known, the same relative heights, and the same events."""
    sc = next(s for s in catalogue("tune") if s.name == name)
    det_ref, ref, ev_ref = _judge(sc, 1.0)
    det_small, small, ev_small = _judge(sc, 1.6 / 1.65)
    assert det_small.camera.fit_scale() == pytest.approx(1.6 / 1.65 * det_ref.camera.fit_scale(), rel=1e-9)
    assert len(ref) > 20 and [t for t, _ in small] == [t for t, _ in ref]
    assert np.allclose([h for _, h in small], [h for _, h in ref], rtol=0.0, atol=1e-9)
    assert ev_small == ev_ref and any(s in ("falling", "on_floor") for s, _ in ev_ref)
