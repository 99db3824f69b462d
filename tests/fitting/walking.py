"""A simulated walking person's body landmarks (1.7 m, walk_left_forward at 30 % of the cycle) as the fit's
inputs, for tests that need a real pose to pack random solutions against (fitting.assemble, fitting.root)."""

from __future__ import annotations

from posed.bench import simulate as S
from posed.camera_model import Intrinsics
from posed.fitting import BodyDimensions, FitConfig
from posed.fitting import problem as P

DIMS = BodyDimensions.from_height(1.7)
CONFIG = FitConfig(body_height_m=1.7)
CAMERA = Intrinsics(900.0, 900.0, 640.0, 360.0, 1280, 720)   # 1280 x 720, the landmarks' image


def walking_weights():
    """(xy, w): the 12 body landmarks in pixels and their weights (fitting.problem.landmark_weights)."""
    xy, w, _ = P.landmark_weights(S.render(S.pose("walk_left_forward", 30.0), dims=DIMS), CONFIG)
    return xy, w
