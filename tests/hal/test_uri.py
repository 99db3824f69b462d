"""URIs, the registry and the frame values."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from posed import hal
from posed.camera_model import Intrinsics
from posed.hal.config import SourceConfig
from posed.hal.frame import Frame
from posed.hal.uri import parse_uri, split_query


def test_uri_forms():
    assert parse_uri("realsense:") == SourceConfig(type="realsense", serial="")
    assert parse_uri("realsense:0123456789") == SourceConfig(type="realsense", serial="0123456789")
    assert parse_uri("v4l2:/dev/video2") == SourceConfig(type="v4l2", device="/dev/video2")
    assert parse_uri("v4l2:1").device == "1"
    cfg = parse_uri("file:/data/x.mp4?realtime=false&loop=1&drop=0.1&stall_at=20&stall_s=3&disconnect_at=40"
                    "&disconnect_s=0&corrupt_at=10&seed=5&fx=615.5")
    assert (cfg.type, cfg.path, cfg.realtime, cfg.loop) == ("file", "/data/x.mp4", False, True)
    assert (cfg.fault_drop, cfg.fault_stall_at, cfg.fault_stall_s, cfg.fault_disconnect_at) == (0.1, 20, 3.0, 40)
    assert (cfg.fault_disconnect_s, cfg.fault_corrupt_at, cfg.fault_seed, cfg.fx) == (0.0, 10, 5, 615.5)
    assert cfg.has_faults and not SourceConfig().has_faults


def test_query_left_in_a_config_path_is_applied(tmp_path):
    # `posed run --source file:x.mp4?drop=0.5` puts the whole rest into source.path
    cfg = split_query(SourceConfig(type="file", path="x.mp4?drop=0.5"))
    assert (cfg.path, cfg.fault_drop) == ("x.mp4", 0.5)
    odd = tmp_path / "what?.mp4"
    odd.write_bytes(b"")
    assert split_query(SourceConfig(type="file", path=str(odd))).path == str(odd)  # an existing name stays


@pytest.mark.parametrize("bad, message", [
    ("x.mp4", "not a source URI"),
    ("webcam:0", "not a source URI"),
    ("v4l2:", "needs a device"),
    ("file:", "needs a path"),
    ("file:a.mp4?colour=red", "unknown option 'colour'"),
    ("file:a.mp4?drop=lots", "drop='lots' is not a float"),
    ("file:a.mp4?drop=2", r"drop=2.0 is out of range \[0.0, 1.0\]"),
    ("file:a.mp4?loop=maybe", "loop='maybe' is not a bool"),
])
def test_bad_uris_are_explained(bad, message):
    with pytest.raises(hal.SourceUnsupported, match=message):
        hal.open_source(bad)


def test_registry_is_explicit_and_extensible(tmp_path):
    assert set(hal.REGISTRY) == {"realsense", "v4l2", "file"}
    with pytest.raises(hal.SourceUnsupported, match="'gige' is not one of"):
        hal.open_source(dataclasses.replace(SourceConfig(), type="gige"))
    made = []

    class Dummy(hal.Source):
        def _open(self): pass
        def _close(self): pass
        def _read(self, timeout_s):
            return Frame(np.zeros((2, 2, 3), np.uint8), None, 0.0, 1.0, 0)

    hal.register("dummy", lambda cfg: made.append(cfg) or Dummy(cfg, "dummy:"))
    try:
        with hal.open_source(dataclasses.replace(SourceConfig(), type="dummy")) as src:
            assert src.read().seq == 0 and src.info["frames"] == 1
    finally:
        del hal.REGISTRY["dummy"]
    assert len(made) == 1


def test_landmark_recording_is_left_to_the_daemon(tmp_path):
    rec = tmp_path / "walk.landmarks.jsonl"
    rec.write_text("{}\n")
    assert hal.is_landmark_recording(rec)
    with pytest.raises(hal.SourceUnsupported, match="landmark recording: the daemon replays it directly"):
        hal.open_source(f"file:{rec}")


def test_empty_path_and_reading_a_closed_source(squat_video):
    with pytest.raises(hal.SourceNotFound, match="without a path"):
        hal.open_source(SourceConfig(type="file", path=""))
    src = hal.open_source(f"file:{squat_video}")
    with pytest.raises(hal.SourceError, match="not open"):
        src.read()
    src.close()  # closing a closed source is fine


def test_errors_are_distinct_and_say_whether_to_retry():
    kinds = [hal.SourceNotFound, hal.SourceUnsupported, hal.SourceCorrupt, hal.SourceTimeout,
             hal.SourceDisconnected, hal.EndOfStream]
    assert len(set(kinds)) == 6 and all(issubclass(k, hal.SourceError) for k in kinds)
    assert [k.retry for k in kinds] == [False, False, True, True, True, False]
    assert hal.SourceTimeout("x", "v4l2:0").source == "v4l2:0"


def test_intrinsics_project_deproject_and_scale():
    k = Intrinsics(fx=600.0, fy=610.0, cx=319.5, cy=239.5, width=640, height=480)
    uv = np.array([[10.0, 20.0], [319.5, 239.5], [600.0, 400.0]])
    z = np.array([0.5, 1.0, 3.0])
    xyz = k.deproject(uv[:, 0], uv[:, 1], z)
    assert np.allclose(xyz[1], [0, 0, 1.0]) and np.allclose(xyz[:, 2], z)
    assert np.allclose(k.project(xyz), uv)
    half = k.scaled(320, 240)
    assert (half.fx, half.fy, half.cx, half.cy) == (300.0, 305.0, 159.5, 119.5)
    # the same 3D point lands on the same place of the resized image
    assert np.allclose((k.project(xyz) + 0.5) / 2 - 0.5, half.project(xyz))
    assert Intrinsics.from_json(k.to_json()) == k


def test_frame_checks_its_arrays():
    img = np.zeros((4, 6, 3), np.uint8)
    f = Frame(img, np.ones((4, 6), np.uint16), 0.001, 12.5, 3, None)
    assert (f.width, f.height) == (6, 4) and f.depth_m().dtype == np.float32
    assert np.allclose(f.depth_m(), 0.001)
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.seq = 4  # type: ignore[misc]
    with pytest.raises(ValueError, match="H x W x 3 uint8 BGR"):
        Frame(np.zeros((4, 6), np.uint8), None, 0.0, 0.0, 0)
    with pytest.raises(ValueError, match="aligned to the image"):
        Frame(img, np.zeros((2, 3), np.uint16), 0.001, 0.0, 0)
