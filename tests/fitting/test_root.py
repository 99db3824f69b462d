"""root_cam_m: where the person is in the camera frame, from the intrinsics and the person's size."""

from __future__ import annotations

import numpy as np
import pytest

from bench import simulate as S
from fitting import BodyDimensions, FitConfig, Fitter


def truth_mid_hip(pose, dims, camera, placement, image_size):
    """The rendered person's mid-hip (between MediaPipe's hip landmarks 23, 24) in the camera frame."""
    cam_h = 1.0 if camera.height_m is None else camera.height_m
    pts, _ = S._world_points(pose, dims, placement, camera.distance_m, cam_h)
    return 0.5 * (pts[23] + pts[24])


@pytest.mark.parametrize("distance, x_m, yaw", [(2.5, 0.0, 30.0), (3.0, 0.6, -60.0), (5.0, -0.8, 120.0)])
def test_root_is_the_rendered_placement(distance, x_m, yaw):
    dims = BodyDimensions.from_height(1.6)
    camera = S.Camera(model="pinhole", distance_m=distance, height_m=1.2)
    placement = S.Placement(x_m=x_m)
    pose = S.pose("stand_arms_front", yaw)
    size = (640, 480)
    lm = S.render(pose, dims=dims, camera=camera, placement=placement, image_size=size)
    r = Fitter(FitConfig(body_height_m=1.6)).fit(lm, 0, 0.0, size, mode="image",
                                                  intrinsics=camera.intrinsics(size))
    assert r.ok, r.reason
    want = truth_mid_hip(pose, dims, camera, placement, size)
    # an exact fit of the model that rendered it: the position to float precision of the fit (1e-3 m)
    np.testing.assert_allclose(r.root_cam_m, want, atol=1e-3)
    assert r.to_json()["root_cam_m"] == list(r.root_cam_m)


def test_a_wrong_body_height_scales_the_distance():
    """Without depth the distance comes from the person's size: a person taken 10 % taller than they are
    is placed 10 % further away."""
    dims = BodyDimensions.from_height(1.6)
    camera = S.Camera(model="pinhole", distance_m=3.0, height_m=1.2)
    lm = S.render(S.pose("stand_arms_front", 30.0), dims=dims, camera=camera, image_size=(640, 480))
    k = camera.intrinsics((640, 480))
    right = Fitter(FitConfig(body_height_m=1.6)).fit(lm, 0, 0.0, (640, 480), mode="image", intrinsics=k)
    tall = Fitter(FitConfig(body_height_m=1.76)).fit(lm, 0, 0.0, (640, 480), mode="image", intrinsics=k)
    assert tall.root_cam_m[2] == pytest.approx(1.1 * right.root_cam_m[2], rel=0.02)


def test_no_intrinsics_no_root():
    lm = S.render(S.pose("stand_arms_front", 30.0))
    r = Fitter().fit(lm, 0, 0.0, (640, 480), mode="image")
    assert r.ok and r.root_cam_m is None and "root_cam_m" not in r.to_json()
