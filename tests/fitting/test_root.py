"""root_cam_m: where the person is in the camera frame, from the intrinsics and the person's size."""

from __future__ import annotations

import numpy as np
import pytest

from posed.bench import simulate as S
from posed.fitting import BodyDimensions, FitConfig, Fitter
from tests.fitting.root_reference import reference_root
from tests.fitting.walking import CAMERA, CONFIG, DIMS, walking_weights


def truth_mid_hip(pose, dims, camera, placement, image_size):
    """The rendered person's mid-hip (between MediaPipe's hip landmarks 23, 24) in the camera frame."""
    cam_h = 1.0 if camera.height_m is None else camera.height_m
    pts, _ = S._world_points(pose, dims, placement, camera.distance_m, cam_h)
    return 0.5 * (pts[23] + pts[24])


@pytest.mark.parametrize("distance, x_m, yaw", [(2.5, 0.0, 30.0), (3.0, 0.6, -60.0), (5.0, -0.8, 120.0)])
def test_root_is_the_rendered_placement(distance, x_m, yaw):
    dims = BodyDimensions.from_height(1.6)
    camera = S.LevelCamera(model="pinhole", distance_m=distance, height_m=1.2)
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
    camera = S.LevelCamera(model="pinhole", distance_m=3.0, height_m=1.2)
    lm = S.render(S.pose("stand_arms_front", 30.0), dims=dims, camera=camera, image_size=(640, 480))
    k = camera.intrinsics((640, 480))
    right = Fitter(FitConfig(body_height_m=1.6)).fit(lm, 0, 0.0, (640, 480), mode="image", intrinsics=k)
    tall = Fitter(FitConfig(body_height_m=1.76)).fit(lm, 0, 0.0, (640, 480), mode="image", intrinsics=k)
    assert tall.root_cam_m[2] == pytest.approx(1.1 * right.root_cam_m[2], rel=0.02)


def test_no_intrinsics_no_root():
    lm = S.render(S.pose("stand_arms_front", 30.0))
    r = Fitter().fit(lm, 0, 0.0, (640, 480), mode="image")
    assert r.ok and r.root_cam_m is None and "root_cam_m" not in r.to_json()


@pytest.mark.parametrize("intrinsics", [False, True])
def test_root_kernel_matches_the_python_sums(intrinsics):
    """The kernel against the same sums in plain Python, to the last bit (with and without a measured depth,
    landmarks left out, points clamped to MIN_DEPTH)."""
    from posed.fitting import forward_kinematics as FK
    from posed.fitting import layout as L
    from posed.fitting import problem as P
    from posed.fitting.root import root_position

    dims, cfg = DIMS, CONFIG
    xy, w = walking_weights()
    k = CAMERA if intrinsics else None
    rng = np.random.default_rng(4)
    for i in range(40):
        wi = w * (rng.random(12) > 0.2)
        if wi.sum() == 0:
            continue
        data = P.pack(xy, wi, dims, cfg, P.reference_scale(xy, w, dims), k).data
        x = P.to_radians(rng.uniform(P.LIMIT_LO, P.LIMIT_HI))
        pts_b, pts_c = np.empty((L.N_POINTS, 3)), np.empty((L.N_POINTS, 3))
        FK.model_points(x, data, pts_b, pts_c)
        if i % 5 == 0:
            pts_c[3, 2] = -1e3   # behind the camera: clamped
        root_z = None if i % 2 else float(rng.uniform(1.0, 6.0))
        want = reference_root(x, data, pts_c, root_z)
        known, *got = root_position(x, data, pts_c, 0.0 if root_z is None else root_z, root_z is not None)
        got = tuple(got) if known else None
        assert (got is None) == (not intrinsics)
        assert got == want and np.array(got, dtype=float).tobytes() == np.array(want, dtype=float).tobytes()
    data[L.D_W:L.D_W + L.N_LM] = 0.0
    assert root_position(x, data, pts_c, 0.0, False) == (False, 0.0, 0.0, 0.0)
