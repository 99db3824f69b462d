"""Night through ``posed run``, real processes end to end: a RealSense recording whose colour stream is
near-black (a room at 3 a.m.) and whose left infrared stream shows a person (MediaPipe's real pose photo in
grey). The daemon watches by infrared: the real landmark model finds the person, poses are published, the
status says ``spectrum`` infrared and the log says once that it switched. The same recording without its
infrared stream leaves the daemon blind, as before."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.client import contract
from posed.commands._viewer import Summary
from posed.daemon.supervisor import status_text
from tests.daemon.replay_util import replay_to_end
from tests.daemon.robots_util import log_events
from tests.daemon.test_run_e2e import posed_run
from tests.daemon.zenoh_util import free_port

SIZE = (480, 320)
FPS = 10.0
FRAMES = 20                 # 2 s
K = Intrinsics(fx=420.0, fy=420.0, cx=239.5, cy=159.5, width=SIZE[0], height=SIZE[1])
IR_K = Intrinsics(fx=400.0, fy=400.0, cx=241.0, cy=158.0, width=SIZE[0], height=SIZE[1])
EX_DATAERR = 65


def write_dark_room(path, shared_data, infrared: bool) -> None:
    from posed.hal.db3 import Db3Writer

    photo = cv2.imread(str(shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg"))
    assert photo is not None, "missing the real test image reference/mediapipe_pose_jpg/pose.jpg"
    photo = cv2.resize(photo, SIZE, interpolation=cv2.INTER_AREA)
    dark = (photo.astype(np.float64) * 0.01).round().astype(np.uint8)       # 0..2: pitch dark
    grey = cv2.cvtColor(photo, cv2.COLOR_BGR2GRAY)
    with Db3Writer(path, K, FPS, infrared=infrared, infrared_intrinsics=IR_K if infrared else None) as w:
        for i in range(FRAMES):
            w.write(dark, None, 1000.0 + i * 1000.0 / FPS, i, **({"infrared": grey} if infrared else {}))


@pytest.mark.timeout(300)
def test_a_dark_room_is_watched_by_infrared(tmp_path, shared_data):
    rec = tmp_path / "night.db3"
    write_dark_room(rec, shared_data, infrared=True)
    run = tmp_path / "run"
    run.mkdir()
    got = replay_to_end(run, rec, "night", ("landmarks", "pose", "status"), "pipeline.status_period_s=0.1",
                        "zenoh.publish_landmarks=true")
    found = [m for m in got["landmarks"] if m.get("landmarks") is not None]
    assert len(found) >= FRAMES - 2, f"the person was found in {len(found)} of {len(got['landmarks'])} frames"
    for m in found:
        nose_x, nose_y = m["landmarks"][0][:2]
        assert 0 <= nose_x < SIZE[0] and 0 <= nose_y < SIZE[1]
    assert [p for p in got["pose"] if p.get("ok")], "no pose fitted"
    cameras = [s["camera"] for s in got["status"] if "spectrum" in s["camera"]]
    assert cameras and cameras[-1]["spectrum"] == "infrared" and cameras[-1]["infrared"] == "in use", cameras[-1:]
    assert isinstance(cameras[-1]["spectrum_since_unix"], float)
    assert all(contract.errors(s) == [] for s in got["status"])
    dark = log_events(run / "out.log", "camera_dark")
    assert len(dark) == 1 and not log_events(run / "out.log", "camera_light"), dark
    assert dark[0]["note"] == "camera: dark, watching by infrared"
    assert "(dark: by infrared)" in status_text(got["status"][-1])
    viewer = Summary()                                  # posed watch's line
    viewer.status = next(s for s in reversed(got["status"]) if s["camera"].get("spectrum") == "infrared")
    assert f"recording {viewer.status['camera']['state']} (dark: by infrared)" in viewer.line(1.0)[-1]


@pytest.mark.timeout(300)
def test_the_same_dark_room_without_infrared_is_blind(tmp_path, shared_data):
    rec = tmp_path / "night_colour_only.db3"
    write_dark_room(rec, shared_data, infrared=False)
    proc = posed_run(tmp_path, rec, "robot_id=blindnight", "source.realtime=false", "pipeline.stop_at_end=true",
                     f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]")
    assert proc.wait(timeout=240) == EX_DATAERR, (tmp_path / "err.log").read_text()
    said = log_events(tmp_path / "out.log", "recording_not_processed")
    assert said and "blank frames" in said[0]["reason"] and "uncover the camera's lens" in said[0]["fix"], said
    assert not log_events(tmp_path / "out.log", "camera_dark")


def test_systemd_status_line_says_the_camera_watches_by_infrared():
    status = {"state": "running", "fps": 10.0, "latency_ms": {"p95": 40.0}, "drops": 0, "restarts": 0,
              "camera": {"state": "open", "source": "realsense:", "kind": "realsense", "spectrum": "infrared"}}
    assert status_text(status).endswith("camera open (dark: by infrared)"), status_text(status)
    status["camera"]["spectrum"] = "colour"
    assert "infrared" not in status_text(status)
