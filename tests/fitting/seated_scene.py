"""A person seated upright seen by a camera pitched down: the scene the fit's down (fitting.vertical) is for."""

from __future__ import annotations

import numpy as np

from posed.falls.features import gravity_from_tilt
from posed.fitting.body import BodyDimensions
from posed.fitting.kinematics import Pose, body_angles_from_rotation, body_rotation
from posed.fitting.vertical import level_frame


def seated_under(tilt_deg: float, dims: BodyDimensions):
    """(landmarks (33 x 5), the camera's intrinsics (640 x 480), its gravity, the pose as the camera sees it) of
    a person seated upright (bench.simulate's ``sit_chair``: hips 86-88, lumbar 4 degrees, turned 30) seen by a
    pinhole camera pitched down ``tilt_deg``."""
    from posed.bench import simulate as S

    g = np.asarray(gravity_from_tilt(tilt_deg))
    level: Pose = S.pose("sit_chair", 30.0)
    t, p, s = body_angles_from_rotation(level_frame(g) @ body_rotation(level.theta_bd, level.phi_bd, level.psi_bd))
    seen = level.replace(theta_bd=t, phi_bd=p, psi_bd=s)
    cam = S.LevelCamera(model="pinhole")
    return S.render(seen, dims=dims, camera=cam), cam.intrinsics((640, 480)), g, seen
