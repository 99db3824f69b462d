"""The seated test reads the hips from the fitted joint positions (issue 33).

The fit's hip angle depends on how its pelvis-tilt prior splits the pelvis tilt between the lumbar spine and the
hips, which no landmark tells apart, and that prior takes the camera's own down as vertical: from a camera 35
deg down a person seated at 90 deg reads 53-73 (docs/bench/fit.md, "Which way is down, given to the fit"). The
angle between the trunk and the thigh does not depend on that split.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.falls.features import gravity_from_tilt, measure


def _seated_frame():
    sc = next(s for s in catalogue("tune", "wall") if s.name == "wall/tune/fall/sitting-forward/fast-v30")
    fr = next(f for f in frames(sc) if f.t >= 1.0)          # seated on the chair (the fall starts at 2 s)
    return sc.camera, fr, truth_result(fr, sc.camera)


def _measure(cam, fr, result):
    g = np.asarray(gravity_from_tilt(cam.tilt, 0.0), float)
    return measure(result, fr.landmarks, (cam.width, cam.height), cam.intrinsics, g, 0.5, 25.0, 0.0, "camera")


def test_a_seated_person_is_seated_whatever_split_the_fit_chose():
    """The same seated joints, reported with the hips at 55 deg and the lumbar spine flexed by the rest (as the
    fit reports them from 35 deg above): still seated. Before, the model's 55 deg failed the 60-120 deg test on
    about half the frames, and a person seen only sitting never rejected a wrong guess of the camera's tilt."""
    cam, fr, res = _seated_frame()
    assert _measure(cam, fr, res).seated_trunk_up_c is not None
    angles = dict(res.joint_angles_deg)
    angles.update(theta_hp_l=55.0, theta_hp_r=55.0)
    biased = _measure(cam, fr, replace(res, joint_angles_deg=angles))
    assert biased is not None and biased.seated_trunk_up_c is not None


def test_a_standing_person_is_not_seated():
    """Standing (the first frame of a scene that starts standing): the trunk and thighs are in line, 0 deg."""
    sc = next(s for s in catalogue("tune", "wall") if s.name == "wall/tune/adl/sit-down-chair/normal-v30")
    fr = next(iter(frames(sc)))
    f = _measure(sc.camera, fr, truth_result(fr, sc.camera))
    assert f is not None and f.seated_trunk_up_c is None and f.upright_legs
