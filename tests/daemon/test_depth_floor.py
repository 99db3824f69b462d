"""The floor from depth in the daemon's stages (issue 33 item 1a): the landmark stage's :class:`DepthFloor` fits
the rendered room's depth image about once a second of capture time (not per frame), within a few ms, with
the accelerometer's gravity as prior; the publisher's :class:`FallWatch` hands the frames' ``floor`` field to
the detector, shows its evidence in the status, forgets it when it is old and counts malformed ones."""

from __future__ import annotations

import statistics
from types import SimpleNamespace

import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.daemon.stages.depth_floor import KEEP_S, DepthFloor
from posed.daemon.stages.fall_watch import FallWatch
from posed.falls import FallsConfig
from posed.falls.features import gravity_from_tilt
from tests.daemon.depth_room import DEPTH_SCALE, Mount, render
from tests.daemon.fakes import RecordingLog

MOUNT = Mount(1.25, 28.0, -2.5)


def _scene(width: int = 640, height: int = 480, mount: Mount = MOUNT):
    cam = mount.camera(width, height)
    depth, _ = render(cam)
    return depth, cam.intrinsics


def _close(field: dict, mount: Mount = MOUNT) -> None:
    assert field["height_m"] == pytest.approx(mount.height_m, abs=0.05)
    assert field["tilt_deg"] == pytest.approx(mount.tilt_deg, abs=2.0)
    assert field["roll_deg"] == pytest.approx(mount.roll_deg, abs=2.0)
    assert np.allclose(field["down"], gravity_from_tilt(mount.tilt_deg, mount.roll_deg), atol=0.035)


def test_fitted_about_once_a_second_of_capture_time_not_per_frame():
    depth, k = _scene()
    floor = DepthFloor()
    fitted = [floor.offer(depth, DEPTH_SCALE, k, None, i / 30.0) for i in range(91)]   # 3 s at 30 fps
    assert [i for i, f in enumerate(fitted) if f] == [0, 30, 60, 90]
    field = floor.field(91 / 30.0)
    _close(field)
    assert field["tries"] == 4 and field["misses"] == 0 and field["prior"] == "none"
    assert field["age_s"] == pytest.approx(1 / 30.0, abs=1e-3)
    assert field["inliers"] > 1000 and 0.2 < field["fraction"] < 1.0 and field["rms_m"] < 0.02
    # the source started again (its clock went back): fitted at once
    assert floor.offer(depth, DEPTH_SCALE, k, None, 0.5)


def test_within_a_few_ms_on_a_640x480_depth_image():
    depth, k = _scene()
    floor = DepthFloor(refresh_s=0.0)
    ms = []
    for i in range(15):
        floor.offer(depth, DEPTH_SCALE, k, None, float(i))
        ms.append(floor.fit_ms)
    assert statistics.median(ms) < 10.0, ms          # measured 2-4 ms (docs/benchmarks.md); loaded machines


def test_a_depth_image_scaled_down_from_the_intrinsics_size():
    """The capture stage scales large frames down (hal.resize); the ring's intrinsics stay the source's."""
    depth, _ = _scene(320, 240)
    _, k_full = _scene(640, 480)
    floor = DepthFloor()
    floor.offer(depth, DEPTH_SCALE, k_full, None, 0.0)
    _close(floor.field(0.0))


def test_the_accelerometer_prior_and_a_fit_again_when_it_first_comes():
    depth, k = _scene()
    floor = DepthFloor()
    assert floor.offer(depth, DEPTH_SCALE, k, None, 0.0)
    assert floor.field(0.0)["prior"] == "none"
    imu = gravity_from_tilt(MOUNT.tilt_deg + 1.0, MOUNT.roll_deg) * 9.8
    assert floor.offer(depth, DEPTH_SCALE, k, tuple(imu), 0.1)           # not waiting the second out
    _close(floor.field(0.1))
    assert floor.field(0.1)["prior"] == "imu"
    assert not floor.offer(depth, DEPTH_SCALE, k, tuple(imu), 0.2)


def test_no_floor_in_view_counts_misses_and_an_old_plane_is_not_sent():
    depth, k = _scene()
    wall = np.full_like(depth, 2000)                # a camera facing a wall
    floor = DepthFloor()
    floor.offer(depth, DEPTH_SCALE, k, None, 0.0)
    floor.offer(wall, DEPTH_SCALE, k, None, 1.0)
    floor.offer(wall, DEPTH_SCALE, k, None, 2.0)
    field = floor.field(2.0)
    assert field["misses"] == 2 and field["tries"] == 3 and field["age_s"] == pytest.approx(2.0)
    assert "down" not in floor.field(KEEP_S + 0.5)                     # too old: only the counters
    none = DepthFloor()
    none.offer(wall, DEPTH_SCALE, k, None, 0.0)
    assert none.field(0.0) == {"tries": 1, "misses": 1, "fit_ms": none.field(0.0)["fit_ms"], "prior": "none"}
    assert DepthFloor().field(0.0) is None                             # nothing fitted yet
    assert not DepthFloor().offer(None, DEPTH_SCALE, k, None, 0.0)     # no depth, no intrinsics: nothing
    assert not DepthFloor().offer(depth, DEPTH_SCALE, None, None, 0.0)


# ---------------------------------------------------------------------------------------------- FallWatch


def _msg(seq: int, t: float, floor: dict | None):
    from posed.fitting import FitResult

    extra = {} if floor is None else {"floor": floor}
    return SimpleNamespace(result=FitResult.failure(seq, t, "no person"),
                           landmarks=SimpleNamespace(landmarks=None, extra=extra, gravity=None),
                           image_size=(640, 480), intrinsics=Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480))


def _field(t_fit: float, t: float) -> dict:
    depth, k = _scene()
    floor = DepthFloor()
    floor.offer(depth, DEPTH_SCALE, k, None, t_fit)
    return floor.field(t)


def test_the_fall_watch_hands_the_floor_to_the_detector_and_the_status_shows_its_evidence():
    watch = FallWatch.from_config(FallsConfig(), "r1", RecordingLog())
    watch.update(_msg(0, 0.0, None))
    assert watch.status()["geometry"]["height_from"] == "config"
    field = _field(0.0, 0.5)
    watch.update(_msg(1, 0.5, field))
    geo = watch.status()["geometry"]
    assert (geo["tilt_from"], geo["roll_from"], geo["height_from"]) == ("depth", "depth", "depth")
    assert geo["floor_below_camera_m"] == pytest.approx(MOUNT.height_m, abs=0.05)
    assert geo["tilt_deg"] == pytest.approx(MOUNT.tilt_deg, abs=2.0)
    evidence = geo["depth_floor"]
    assert evidence["age_s"] == pytest.approx(0.5) and evidence["inliers"] == field["inliers"]
    assert {"fraction", "rms_m", "tries", "misses", "fit_ms", "prior", "tilt_deg", "roll_deg"} <= set(evidence)
    # frames without the field (a lost depth stream): the plane ages, then is forgotten
    watch.update(_msg(2, 10.0, None))
    assert watch.status()["geometry"]["depth_floor"]["age_s"] == pytest.approx(10.0)
    watch.update(_msg(3, KEEP_S + 1.0, None))
    geo = watch.status()["geometry"]
    assert geo["height_from"] == "config" and geo["tilt_from"] == "config"


def test_floor_from_depth_off_ignores_the_field():
    watch = FallWatch.from_config(FallsConfig(floor_from_depth=False), "r1", RecordingLog())
    watch.update(_msg(0, 0.5, _field(0.0, 0.5)))
    assert watch.status()["geometry"]["height_from"] == "config"


def test_tried_and_no_floor_found_is_in_the_status():
    watch = FallWatch.from_config(FallsConfig(), "r1", RecordingLog())
    watch.update(_msg(0, 0.0, {"tries": 2, "misses": 2, "fit_ms": 1.5, "prior": "none"}))
    geo = watch.status()["geometry"]
    assert geo["height_from"] == "config" and geo["depth_floor"] == {"tries": 2, "misses": 2, "fit_ms": 1.5,
                                                                      "prior": "none"}


@pytest.mark.parametrize("bad", ["up", {"down": [0, 0, 0], "height_m": 1.0}, {"down": [0, 1], "height_m": 1.0},
                                 {"down": [0, 1, 0], "height_m": -1.0}, {"down": [0, 1, 0]},
                                 {"down": [0, 1, 0], "height_m": 1.0, "age_s": -3}])
def test_a_malformed_floor_is_counted_and_the_geometry_kept(bad):
    log = RecordingLog()
    watch = FallWatch.from_config(FallsConfig(), "r1", log)
    watch.update(_msg(0, 0.5, _field(0.0, 0.5)))
    watch.update(_msg(1, 0.6, bad))
    assert watch.bad_floor == 1 and watch.status()["bad_floor"] == 1
    assert watch.status()["geometry"]["height_from"] == "depth"
    assert [e for _lv, e, _f in log.lines if e == "depth_floor_bad"]
