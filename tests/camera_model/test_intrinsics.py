"""camera_model.Intrinsics: the pinhole maths against plain NumPy, the field-of-view camera, validation and the
two JSON forms (hal's sidecar with the image size, the landmark recording's ``camera`` without it)."""

import json
import math
import pickle

import numpy as np
import pytest

from posed.camera_model import Intrinsics

K = Intrinsics(fx=615.2, fy=612.8, cx=322.4, cy=241.1, width=640, height=480)


def _matrix(k: Intrinsics) -> np.ndarray:
    return np.array([[k.fx, 0.0, k.cx], [0.0, k.fy, k.cy], [0.0, 0.0, 1.0]])


def _points(rng, n=200) -> np.ndarray:
    return np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.0, 1.0, n), rng.uniform(0.3, 8.0, n)])


def test_project_and_deproject_match_the_camera_matrix():
    rng = np.random.default_rng(4)
    xyz = _points(rng)
    h = xyz @ _matrix(K).T                                  # homogeneous pixels of x = K X
    uv_ref = h[:, :2] / h[:, 2:]
    np.testing.assert_allclose(K.project(xyz), uv_ref, rtol=0, atol=1e-9)
    rays = np.column_stack([uv_ref, np.ones(len(uv_ref))]) @ np.linalg.inv(_matrix(K)).T
    np.testing.assert_allclose(K.deproject(uv_ref[:, 0], uv_ref[:, 1], xyz[:, 2]), rays * xyz[:, 2:], atol=1e-9)
    np.testing.assert_allclose(K.deproject(*K.project(xyz).T, xyz[:, 2]), xyz, atol=1e-9)   # round trip
    assert K.project(xyz[:3].reshape(1, 3, 3)).shape == (1, 3, 2)                           # any leading shape
    assert K.deproject(K.cx, K.cy, 2.0).tolist() == [0.0, 0.0, 2.0]


def test_scaled_is_a_resize_of_the_image():
    rng = np.random.default_rng(5)
    xyz = _points(rng)
    for w, h in ((320, 240), (1280, 720), (640, 480)):
        s = K.scaled(w, h)
        assert (s.width, s.height) == (w, h)
        sx, sy = w / K.width, h / K.height
        # a resize maps pixel centres: u' + 0.5 = (u + 0.5) * sx
        resize = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
        np.testing.assert_allclose(_matrix(s), resize @ _matrix(K), rtol=1e-12)
        uv = np.column_stack([K.project(xyz), np.ones(len(xyz))]) @ resize.T
        np.testing.assert_allclose(s.project(xyz), uv[:, :2], atol=1e-9)
    assert K.scaled(640, 480) is K
    assert K.scaled(320, 240).scaled(640, 480) == K


def test_from_hfov():
    k = Intrinsics.from_hfov(69.0, 640, 480)
    assert k == Intrinsics(320.0 / math.tan(math.radians(34.5)), 320.0 / math.tan(math.radians(34.5)), 320.0,
                           240.0, 640, 480)
    # the field of view is what the focal length says: the image's left and right edges at +-hfov/2
    edge = k.deproject(np.array([0.0, 640.0]), 240.0, 1.0)
    assert math.degrees(math.atan2(edge[1, 0], 1.0) - math.atan2(edge[0, 0], 1.0)) == pytest.approx(69.0)
    assert Intrinsics.from_hfov(90.0, 100, 50).fx == pytest.approx(50.0)


def test_an_assumed_lens_says_so_through_resizing_and_json():
    k = Intrinsics.assume(69.0, 640, 480)
    assert k.assumed and not Intrinsics.from_hfov(69.0, 640, 480).assumed
    assert (k.fx, k.cx, k.size) == (Intrinsics.from_hfov(69.0, 640, 480).fx, 320.0, (640, 480))
    assert k != Intrinsics.from_hfov(69.0, 640, 480)      # a measured lens is not an assumed one
    assert k.scaled(320, 240).assumed and k.scaled(320, 240).scaled(640, 480) == k
    assert k.to_json()["assumed"] is True and "assumed" not in Intrinsics.from_hfov(69.0, 640, 480).to_json()
    assert Intrinsics.from_json(k.to_json()) == k
    assert Intrinsics.from_json(k.to_json(with_size=False), (640, 480)) == k
    with pytest.raises(ValueError, match="assumed must be true or false"):
        Intrinsics.from_json({**k.to_json(), "assumed": "yes"})
    # a portrait image is the same camera turned: the field of view spans its long (vertical) side
    p = Intrinsics.assume(69.0, 480, 640)
    assert (p.fx, p.fy, p.cx, p.cy, p.size, p.assumed) == (k.fx, k.fy, 240.0, 320.0, (480, 640), True)
    edge = p.deproject(240.0, np.array([0.0, 640.0]), 1.0)
    assert math.degrees(math.atan2(edge[1, 1], 1.0) - math.atan2(edge[0, 1], 1.0)) == pytest.approx(69.0)


def test_values_are_normalised_and_checked():
    k = Intrinsics(np.float32(600.0), 600, 320, np.float64(240.0), np.int64(640), 480.0)
    assert all(type(getattr(k, f)) is float for f in ("fx", "fy", "cx", "cy"))
    assert type(k.width) is int and type(k.height) is int and k.size == (640, 480)
    assert json.dumps(k.to_json()) == json.dumps(Intrinsics(600.0, 600.0, 320.0, 240.0, 640, 480).to_json())
    for bad in ((0.0, 600.0, 320.0, 240.0, 640, 480), (600.0, -1.0, 320.0, 240.0, 640, 480),
                (600.0, 600.0, math.nan, 240.0, 640, 480), (600.0, 600.0, 320.0, math.inf, 640, 480),
                (600.0, 600.0, 320.0, 240.0, 0, 480), (600.0, 600.0, 320.0, 240.0, 640, 480.5),
                (600.0, 600.0, 320.0, 240.0, None, 480), ("x", 600.0, 320.0, 240.0, 640, 480)):
        with pytest.raises(ValueError):
            Intrinsics(*bad)
    with pytest.raises(AttributeError):
        K.fx = 1.0                                           # frozen


def test_json_with_size_round_trips_and_pickles():
    obj = json.loads(json.dumps(K.to_json()))
    assert obj == {"fx": 615.2, "fy": 612.8, "cx": 322.4, "cy": 241.1, "width": 640, "height": 480}
    assert Intrinsics.from_json(obj) == K
    assert pickle.loads(pickle.dumps(K, protocol=5)) == K
    with pytest.raises(ValueError, match="width and height"):
        Intrinsics.from_json({"fx": 1.0, "fy": 1.0, "cx": 0.0, "cy": 0.0})
    with pytest.raises(ValueError, match="fy must be a number"):
        Intrinsics.from_json({"fx": 1.0, "fy": "1", "cx": 0.0, "cy": 0.0, "width": 2, "height": 2})


def test_recording_camera_json_is_the_old_four_numbers():
    """The landmark recording's header ``camera`` (interfaces.md section 1): fx, fy, cx, cy only, the size from
    the header's image_size; written exactly as before."""
    from posed.landmarks.recording import RecordingHeader

    old_line = ('{"format": "posed.landmarks", "version": 1, "image_size": [640, 480], "fps": 30.0, '
                '"source": "cam", "camera": {"fx": 600.0, "fy": 601.0, "cx": 320.0, "cy": 240.5}}')
    header = RecordingHeader.from_json(json.loads(old_line))
    assert header.camera == Intrinsics(600.0, 601.0, 320.0, 240.5, 640, 480)
    assert json.dumps(header.to_json()) == old_line
    assert json.dumps(header.camera.to_json(with_size=False)) == '{"fx": 600.0, "fy": 601.0, "cx": 320.0, "cy": 240.5}'
    assert Intrinsics.from_json(header.camera.to_json(with_size=False), image_size=(640, 480)) == header.camera
    ints = json.loads(old_line.replace("600.0", "600"))            # integers in the file read as before
    assert json.dumps(RecordingHeader.from_json(ints).to_json()) == old_line
    with pytest.raises(ValueError, match="image_size"):
        RecordingHeader((320, 240), 30.0, camera=header.camera)      # intrinsics of another image size
    with pytest.raises(ValueError, match="camera"):
        RecordingHeader.from_json({**json.loads(old_line), "camera": {"fx": 0.0, "fy": 1.0, "cx": 0.0, "cy": 0.0}})
