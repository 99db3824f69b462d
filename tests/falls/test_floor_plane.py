"""The floor plane from a depth point cloud (issue 33 item 1a; falls.floor_plane): synthetic rooms seen by a
depth camera — floor, walls, a table, a bed, a standing person, depth noise and stray points — give the
camera's height within 5 cm and its tilt and roll within 2 deg, with or without an IMU prior."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.bench.falls_body import WorldCamera
from posed.falls.features import gravity_from_tilt
from posed.falls.floor_plane import fit_floor, points_from_depth


def _box(rng, lo, hi, n):
    return rng.uniform(lo, hi, size=(n, 3))


def room(cam: WorldCamera, seed: int = 0, floor_points: int = 3000, clutter: bool = True) -> np.ndarray:
    """World points of a room in front of ``cam`` (x east, y north, z up), seen in camera axes, with depth
    noise of 1 % of the range (a RealSense at 1-4 m) and 3 % stray points."""
    rng = np.random.default_rng(seed)
    parts = [_box(rng, (-2.0, 0.6, 0.0), (2.0, 5.0, 0.0), floor_points)]                 # the floor
    parts.append(_box(rng, (-2.0, 5.0, 0.0), (2.0, 5.0, 2.6), 2500))                      # back wall
    parts.append(_box(rng, (-2.0, 0.6, 0.0), (-2.0, 5.0, 2.6), 1500))                     # side wall
    if clutter:
        parts.append(_box(rng, (0.3, 2.0, 0.75), (1.5, 2.8, 0.75), 1500))                 # a table top
        parts.append(_box(rng, (-1.8, 3.0, 0.5), (-0.4, 4.9, 0.5), 2500))                 # a bed
        t = rng.uniform(0, 2 * math.pi, 800)
        z = rng.uniform(0.0, 1.7, 800)
        parts.append(np.stack([0.2 * np.cos(t) - 0.5, 0.2 * np.sin(t) + 2.5, z], axis=1))  # a person
    world = np.concatenate(parts)
    pc = np.array([cam.to_camera(w) for w in world])
    pc = pc[pc[:, 2] > 0.3]
    pc *= 1.0 + rng.normal(0.0, 0.01, size=(len(pc), 1))                                   # noise along the ray
    stray = rng.uniform((-3, -2, 0.3), (3, 3, 6), size=(len(pc) * 3 // 100, 3))
    return np.concatenate([pc, stray])


@pytest.mark.parametrize("height,tilt,roll", [(1.1, 25.0, -3.0), (0.6, 10.0, 2.0), (2.0, 35.0, 0.0),
                                              (1.3, 0.0, 4.0)])
def test_height_tilt_and_roll_from_the_floor_without_a_prior(height, tilt, roll):
    cam = WorldCamera(z=height, tilt=tilt, roll=roll)
    plane = fit_floor(room(cam, seed=int(height * 10)))
    assert plane is not None
    assert abs(plane.height_m - height) < 0.05
    assert abs(plane.tilt_deg - tilt) < 2.0 and abs(plane.roll_deg - roll) < 2.0
    assert np.allclose(plane.down, gravity_from_tilt(tilt, roll), atol=math.radians(2.5))


def test_with_the_imu_prior_a_cluttered_room_still_gives_the_floor():
    cam = WorldCamera(z=1.0, tilt=20.0, roll=1.5)
    imu = gravity_from_tilt(21.5, 0.5) * 9.81                   # an uncalibrated accelerometer, 1-2 deg off
    plane = fit_floor(room(cam, seed=7, floor_points=900), prior_down=imu)
    assert plane is not None and abs(plane.height_m - 1.0) < 0.05
    assert abs(plane.tilt_deg - 20.0) < 2.0 and abs(plane.roll_deg - 1.5) < 2.0


def test_a_table_or_bed_is_not_taken_for_the_floor():
    """More points on the bed and table than on the visible floor: the lowest supported plane is the floor."""
    cam = WorldCamera(z=1.2, tilt=30.0)
    plane = fit_floor(room(cam, seed=3, floor_points=700))
    assert plane is not None and abs(plane.height_m - 1.2) < 0.05


def test_no_floor_in_view_is_none():
    cam = WorldCamera(z=1.2, tilt=0.0)
    rng = np.random.default_rng(1)
    wall = np.array([cam.to_camera(w) for w in _box(rng, (-2.0, 3.0, 0.9), (2.0, 3.0, 2.4), 3000)])
    assert fit_floor(wall) is None
    assert fit_floor(np.zeros((10, 3))) is None


def test_points_from_a_depth_image():
    """A depth image of a flat floor seen by a camera 0.9 m up, 15 deg down, deprojected and fitted."""
    cam = WorldCamera(z=0.9, tilt=15.0, width=160, height=120)
    k = cam.intrinsics
    g = gravity_from_tilt(15.0, 0.0)
    v, u = np.mgrid[0:120, 0:160]
    rays = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u, float)], axis=-1)
    along = rays @ g
    depth = np.where(along > 0.05, 0.9 / np.where(along > 0.05, along, 1.0), 0.0)    # z of the floor point
    pts = points_from_depth(depth, k, stride=2)
    plane = fit_floor(pts)
    assert plane is not None and abs(plane.height_m - 0.9) < 0.01 and abs(plane.tilt_deg - 15.0) < 0.5


@pytest.mark.parametrize("height,tilt,roll,room_seed,fit_seed", [(2.0, 35.0, 0.0, 0, 0), (2.0, 35.0, 0.0, 1, 0),
                                                                 (2.0, 35.0, 0.0, 3, 4), (1.5, 45.0, -2.0, 0, 7)])
def test_a_plane_cut_across_the_table_and_the_bed_steps_down_to_the_floor(height, tilt, roll, room_seed, fit_seed):
    """A high camera looking steeply down at a small floor: the table top and the bed together hold more points
    than the floor, and a plane cut across both wins the RANSAC (its normal some 5 deg off, its height the
    table's); the floor is the plane near its normal among the points under it."""
    cam = WorldCamera(z=height, tilt=tilt, roll=roll)
    points = room(cam, seed=room_seed, floor_points=700)
    points = points[np.random.default_rng(room_seed).choice(len(points), 4000, replace=False)]
    plane = fit_floor(points, seed=fit_seed)
    assert plane is not None and abs(plane.height_m - height) < 0.05
    assert abs(plane.tilt_deg - tilt) < 2.0 and abs(plane.roll_deg - roll) < 2.0
