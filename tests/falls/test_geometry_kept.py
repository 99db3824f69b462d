"""The camera geometry learned from people is kept across restarts in the state dir, per camera (issue 33 item
1b): the publisher stage's FallWatch writes it and takes it back; a changed configuration or an unreadable file
is not taken back. Real files in a temporary state dir; the detector on ground-truth fits of the simulated body."""

from __future__ import annotations

import json
import stat
from types import SimpleNamespace

from posed.bench.falls_scenarios import catalogue, frames, truth_result
from posed.daemon.messages import FitMsg
from posed.daemon.stages.fall_watch import FallWatch, geometry_file
from posed.falls import FallsConfig
from posed.landmarks import LandmarkFrame
from tests.daemon.fakes import RecordingLog

WALL = {sc.name: sc for sc in catalogue("tune", "wall")}
STANDING = "wall/tune/adl/squat/normal-v30"          # stands, squats, stands: the body shows the 35 deg tilt
FOUND = "wall/tune/fall/found-lying-backward/v100"    # on the floor from the first frame: never seen standing


def feed(watch: FallWatch, name: str) -> list:
    sc = WALL[name]
    out = []
    for fr in frames(sc):
        msg = FitMsg(truth_result(fr, sc.camera), LandmarkFrame(fr.seq, fr.t, fr.landmarks), fr.t,
                     (sc.camera.width, sc.camera.height))
        out += watch.update(msg)
    return out


def watch_for(path, log=None, cfg: FallsConfig | None = None) -> FallWatch:
    w = FallWatch.from_config(cfg or FallsConfig(), "r1", log or RecordingLog(), state_file=path)
    w.detector.fit_frame = "camera"          # ground-truth joints are in camera axes
    return w


def test_the_file_is_named_per_camera(tmp_path):
    a = geometry_file(tmp_path, SimpleNamespace(type="realsense", serial="123456"))
    b = geometry_file(tmp_path, SimpleNamespace(type="realsense", serial=""))
    c = geometry_file(tmp_path, SimpleNamespace(type="v4l2", device="/dev/video2"))
    assert a.name == "falls-geometry-realsense-123456.json" and b.name == "falls-geometry-realsense-any.json"
    assert c.name == "falls-geometry-v4l2-_dev_video2.json" and len({a, b, c}) == 3
    assert all(p.parent == tmp_path for p in (a, b, c))


def test_learned_geometry_survives_a_restart_and_catches_a_fall_never_seen_standing(tmp_path):
    path = tmp_path / "falls-geometry-v4l2-video0.json"
    first = watch_for(path)
    assert feed(first, STANDING) == []
    first.close()
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    state = json.loads(path.read_text())
    assert state["gravity_from"] == "body" and state["body"]["seconds"] >= 1.0 and state["floor"] is not None

    log = RecordingLog()
    second = watch_for(path, log)                 # a restart: nothing seen yet, the geometry is back
    geo = second.status()["geometry"]
    assert geo["restored"] is True and geo["tilt_from"] == "body" and geo["height_from"] == "learned"
    assert abs(geo["tilt_deg"] - 35.0) < 6.0
    assert any(e == "falls_geometry_restored" for _lv, e, _f in log.lines)
    events = feed(second, FOUND)
    assert [e.state for e in events][:1] == ["on_floor"]
    assert events[0].extra["geometry"]["gravity"] == "body"
    assert events[0].extra["geometry"]["lens"] == "assumed"      # the wall camera's frames carry no intrinsics

    fresh = watch_for(tmp_path / "other-camera.json")     # the same person found lying, nothing kept
    assert feed(fresh, FOUND) == []


def test_a_changed_configuration_is_not_restored(tmp_path):
    path = tmp_path / "falls-geometry-file-x.json"
    w = watch_for(path)
    feed(w, STANDING)
    w.close()
    log = RecordingLog()
    again = watch_for(path, log, FallsConfig(camera_tilt_deg=30.0, camera_height_m=2.0))
    assert again.status()["geometry"]["restored"] is False
    reasons = [f["reason"] for _lv, e, f in log.lines if e == "falls_geometry_not_restored"]
    assert reasons and "camera_tilt_deg" in reasons[0]


def test_an_unreadable_file_is_set_aside_and_detection_goes_on(tmp_path):
    path = tmp_path / "falls-geometry-file-y.json"
    path.write_text('{"version": 1, "gravity": [0, 1')
    log = RecordingLog()
    w = watch_for(path, log)
    assert not path.exists() and len(list(tmp_path.glob("falls-geometry-file-y.json.corrupt-*"))) == 1
    warned = [f for _lv, e, f in log.lines if e == "falls_geometry_unreadable"]
    assert warned and warned[0]["file"] == str(path) and "fix" in warned[0]
    assert feed(w, STANDING) == []
    w.close()
    assert json.loads(path.read_text())["version"] == 1


def test_a_state_dir_that_cannot_be_written_is_reported_not_fatal(tmp_path):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("x")
    w = watch_for(blocker / "falls-geometry-z.json")
    feed(w, STANDING)
    assert w.save() is False and "geometry_save_error" in w.status()
