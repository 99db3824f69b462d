"""The floor learned from a walking person's stance foot, and a floor that changes source without a step in the
heights (issue 33).

Ground-truth fits of the simulated body (``truth_result``), so each rule is tested alone; the real fit is
measured by ``posed bench falls --mount corner`` and the cross-source check (docs/bench/falls.md, "Walking
feet teach the floor").
"""

from __future__ import annotations

import numpy as np

from posed.bench.falls_body import WorldCamera
from posed.bench.falls_scenarios import catalogue, frames, make, truth_result, walk
from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector


def _walking(tilt: float = 25.0, z: float = 2.4):
    path = [(-1.4, 3.2), (1.4, 3.4), (1.2, 4.6), (-1.3, 4.4), (-1.2, 3.0), (1.3, 3.1)]
    sc = make("walk-across", "adl", walk(path, start_pause=0.0), 0.0, 3.5, z, tilt, 31)
    sc.camera = WorldCamera(z=z, tilt=tilt)
    return sc


def test_a_walking_person_teaches_the_floor():
    """A camera whose height was configured 0.4 m off (or whose metres are the fit's, through an assumed lens),
    a person only ever seen walking (a bent swing knee: never a standing frame with both legs straight): the
    lower ankle is the stance foot, on the floor, so the floor is learned from it. Before, the configured floor
    stayed, and a walking pelvis read far from its standing height."""
    sc = _walking()
    cam = sc.camera
    cfg = FallsConfig(camera_tilt_deg=cam.tilt, camera_height_m=cam.z + 0.4, camera_geometry="measured")
    det = FallDetector(cfg, "r", fit_frame="camera")
    walked = [fr for fr in frames(sc) if 0.2 <= fr.t <= sc.duration - 0.6]
    upright = 0
    for fr in walked:
        det.update(truth_result(fr, cam), fr.landmarks, (cam.width, cam.height), cam.intrinsics)
        upright += det.last_features is not None and det.last_features.upright_legs
    assert upright < 5                                # fewer than the five a floor needs from standing feet
    assert det.camera.floor_source == "learned"
    assert abs(det.camera.floor_below_camera - cam.z) < 0.08
    assert 0.85 < det.last_sample.h_rel < 1.15        # the pelvis at about its standing height


def test_a_floor_learned_in_place_of_the_configured_one_is_no_descent():
    """The configured floor 0.5 m below the true one: when the floor learned from the standing feet replaces it
    (the fifth observation), every height drops by 0.5 m at once. That step is no motion of the body: the
    heights seen before are re-expressed against the new floor, and no descent starts (before, the step read
    as a fall-speed descent, which could swallow the real one that followed, urfd_08)."""
    sc = next(s for s in catalogue("tune") if s.name == "tune/adl/sit-down-chair/normal-v30")
    cam = sc.camera
    cfg = FallsConfig(camera_tilt_deg=cam.tilt, camera_height_m=cam.z + 0.5, camera_geometry="measured")
    det = FallDetector(cfg, "r", fit_frame="camera")
    speeds, sources = [], []
    for fr in frames(sc):
        if fr.t > 1.2:                                # still standing (the descent onto the chair starts at 1.5 s)
            break
        det.update(truth_result(fr, cam), fr.landmarks, (cam.width, cam.height), cam.intrinsics)
        speeds.append(det._last_v)
        sources.append(det.camera.floor_source)
    assert sources[0] == "config" and sources[-1] == "learned"
    assert max(speeds) < 0.3 and det._descent is None
    hs = [s.h_rel for s in det._samples]
    assert np.ptp(hs) < 0.1 and 0.9 < hs[-1] < 1.1
