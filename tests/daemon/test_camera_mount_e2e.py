"""The camera's pose from the robot through ``posed run``, real processes and real Zenoh end to end
(``falls.camera_mount_from_bus``; docs/falls.md, "The camera's pose from the robot").

A recording of a fall seen by a camera 2 m up and 35 deg down (bench.falls_scenarios' wall mount: the default
config guesses a level camera 1 m up and misses this fall), replayed paced (capture times on the monotonic
clock, as a live camera's) by a daemon joined to a router on 127.0.0.1; a test-side Zenoh session stands in
for the robot's software and puts the camera's true pose on ``posed/ROBOT/camera/mount`` at 10 Hz. The status'
geometry says ``robot``, the fall is caught and its event says ``robot``, and the fit's vertical is the robot's
down. Without the key enabled (the robot still putting), nothing is taken from it. Garbage on the key (random
bytes, wrong types, NaN, a huge payload, a newer version) is counted as rejected, logged a handful of times, and
changes nothing."""

from __future__ import annotations

import json
import math
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from posed.bench.falls_scenarios import catalogue, frames
from posed.client import contract
from posed.landmarks.recording import LandmarkFrame, RecordingHeader, write_recording
from tests.daemon.test_run_e2e import posed_run
from tests.daemon.zenoh_util import client, free_port, router

SCENE = "wall/tune/fall/sitting-sideways/fast-v100"    # missed on the default guess (docs/bench/falls.md)
ROBOT = "mount"
SOURCE = "tf:base_link->camera_color_optical_frame"
PUT_HZ = 10.0


def _scene():
    return next(s for s in catalogue("tune", "wall") if s.name == SCENE)


def _recording(path: Path) -> Path:
    sc = _scene()
    cam = sc.camera
    write_recording(path, RecordingHeader((cam.width, cam.height), sc.fps, "synthetic wall camera fall", cam.intrinsics),
                    [LandmarkFrame(fr.seq, fr.t, fr.landmarks) for fr in frames(sc)])
    return path


def _true_down() -> list[float]:
    """Gravity in the scene camera's axes, from the camera's own axes (not from its tilt and roll)."""
    return [float(v) for v in _scene().camera.axes @ np.array([0.0, 0.0, -1.0])]


def _angle(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


def _run(tmp_path: Path, payloads, *overrides: str) -> dict:
    """The daemon on the recording (paced, stopping at its end) behind a router; while it runs, a thread puts
    ``payloads()`` (a list of bytes each tick) on the camera/mount key at PUT_HZ from before its start. What was
    received on status, events/fall and pose, how many payloads were put, and the daemon's log lines."""
    rec = _recording(tmp_path / "wall.landmarks.jsonl")
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    lock = threading.Lock()
    got: dict[str, list] = {"status": [], "events/fall": [], "pose": []}
    stop = threading.Event()
    put = [0]

    def keep(into: list):
        def on(sample) -> None:
            with lock:
                into.append(json.loads(sample.payload.to_string()))
        return on

    try:
        with client(rep) as s:
            subs = [s.declare_subscriber(f"posed/{ROBOT}/{k}", keep(v)) for k, v in got.items()]

            def robot() -> None:
                while not stop.is_set():
                    for p in payloads():
                        s.put(f"posed/{ROBOT}/camera/mount", p)
                        put[0] += 1
                    stop.wait(1.0 / PUT_HZ)

            putter = threading.Thread(target=robot, daemon=True)
            putter.start()
            proc = posed_run(tmp_path, rec, f"robot_id={ROBOT}", "source.realtime=true", "pipeline.stop_at_end=true",
                             "pipeline.status_period_s=0.2", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]",
                             f"zenoh.connect=[{rep}]", *overrides)
            try:
                code = proc.wait(timeout=120)
            finally:
                if proc.poll() is None:
                    proc.kill()
                stop.set()
                putter.join(5)
            time.sleep(0.3)
            del subs
        assert code == 0, (tmp_path / "err.log").read_text()[-3000:]
    finally:
        r.close()
    lines = [json.loads(line) for line in (tmp_path / "out.log").read_text().splitlines() if line.startswith("{")]
    with lock:
        return {**{k: list(v) for k, v in got.items()}, "put": put[0], "log": lines}


def _mount(**fields) -> bytes:
    return json.dumps({"format": "posed.camera_mount", "version": 1, "time_unix": time.time(), **fields}).encode()


def _geometries(statuses: list[dict]) -> list[dict]:
    return [s["falls"]["geometry"] for s in statuses if s.get("falls", {}).get("geometry")]


def _falls(events: list[dict]) -> list[dict]:
    return list({(e["id"], e["state"]): e for e in events if e["state"] in ("falling", "on_floor")}.values())


@pytest.mark.timeout(300)
def test_the_robots_camera_pose_gives_the_geometry_and_the_fall_is_caught(tmp_path):
    sc = _scene()
    down = _true_down()
    got = _run(tmp_path, lambda: [_mount(down=[2.0 * v for v in down], height_m=sc.camera.z, source=SOURCE)],
               "falls.camera_mount_from_bus=true")
    geos = [g for g in _geometries(got["status"]) if g.get("tilt_from") == "robot"]
    assert geos, f"no status with the robot's geometry: {_geometries(got['status'])[-2:]}"
    geo = geos[-1]
    assert (geo["tilt_from"], geo["roll_from"], geo["height_from"]) == ("robot", "robot", "robot")
    assert geo["tilt_deg"] == pytest.approx(sc.camera.tilt, abs=0.01)
    assert geo["roll_deg"] == pytest.approx(sc.camera.roll, abs=0.01)
    assert geo["floor_below_camera_m"] == pytest.approx(sc.camera.z, abs=1e-6)
    mount = geo["robot_mount"]
    assert mount["in_force"] is True and mount["source"] == SOURCE and mount["rejected"] == 0
    assert mount["last_error"] is None and mount["received"] >= 10
    assert 0.0 <= mount["age_s"] < 1.0 and mount["samples"] >= 1 and mount["height_m"] == pytest.approx(sc.camera.z)

    caught = _falls(got["events/fall"])
    assert caught, "the fall was not caught with the robot's pose"
    for ev in caught:
        g = ev["geometry"]
        assert (g["gravity"], g["floor"]) == ("robot", "robot"), g
        assert g["robot_mount"]["source"] == SOURCE and 0.0 <= g["robot_mount"]["age_s"] <= 1.0
    first = min(caught, key=lambda e: e["t_detect"])
    assert first["t_detect"] - first["t_impact"] <= 1.5
    # the shipped schemas accept what the daemon now sends (the robot as a geometry source, its evidence)
    robot_status = [s for s in got["status"] if s.get("falls", {}).get("geometry", {}).get("tilt_from") == "robot"]
    bad = [contract.errors(m) for m in [*caught, robot_status[-1]] if contract.errors(m)]
    assert not bad, bad

    # the fit's vertical is the robot's down on the frames it covers (every frame: it was put before the first)
    fitted = [p for p in got["pose"] if p["ok"]]
    assert len(fitted) >= 40
    with_robot = [p for p in fitted if p.get("vertical") == "gravity" and _angle(p["down"], down) < 0.01]
    assert len(with_robot) >= 0.9 * len(fitted), [p.get("down") for p in fitted[:3]]
    # the kept geometry file holds what was learned from people (nothing: the robot covered every frame), never
    # the robot's pose
    kept = [json.loads(f.read_text()) for f in (tmp_path / "state").glob("falls-geometry-*.json")]
    assert kept and kept[0]["gravity_from"] != "robot" and _angle(kept[0]["gravity"], down) > 30.0
    assert kept[0]["body"]["seconds"] == 0.0 and kept[0]["floor"] is None
    # the log says when the poses start and are in force, never per message
    names = [line.get("event") for line in got["log"]]
    assert names.count("camera_mount_received") == 1 and names.count("camera_mount_in_force") >= 1
    assert len([n for n in names if n and n.startswith("camera_mount")]) <= 5


@pytest.mark.timeout(300)
def test_without_the_key_enabled_nothing_is_taken_from_the_robot(tmp_path):
    """The same run, the robot putting the same poses, ``falls.camera_mount_from_bus`` at its default (off):
    no subscriber, the other sources as always, and nothing in the status about the robot."""
    sc = _scene()
    got = _run(tmp_path, lambda: [_mount(down=_true_down(), height_m=sc.camera.z, source=SOURCE)],
               "falls.camera_mount_from_bus=false")
    geos = _geometries(got["status"])
    assert geos and all(g["tilt_from"] != "robot" and g["height_from"] != "robot" for g in geos)
    assert all("robot_mount" not in g for g in geos)
    assert all(e["geometry"]["gravity"] != "robot" for e in got["events/fall"])
    assert not any(p.get("vertical") for p in got["pose"] if p["ok"])      # the default guess: no fit vertical
    assert _falls(got["events/fall"]) == []          # the fall the robot's pose catches is missed on the guess


def _garbage(rng: np.random.Generator) -> list[bytes]:
    return [
        rng.bytes(int(rng.integers(1, 300))),                                  # random bytes
        b"\xff\xfe not utf-8",
        b"[1, 2, 3]",
        json.dumps({"down": "down"}).encode(),                                 # wrong types
        json.dumps({"down": [0, 1, True]}).encode(),
        json.dumps({"tilt_deg": "35", "roll_deg": 0}).encode(),
        b'{"down": [NaN, 1, 0], "height_m": 2.0}',                             # NaN, infinity
        b'{"tilt_deg": 35, "roll_deg": 0, "height_m": Infinity}',
        json.dumps({"down": [0, 0, 0]}).encode(),                              # all 0
        json.dumps({"tilt_deg": 135, "roll_deg": 0}).encode(),                 # out of range
        json.dumps({"down": [0, 1, 0], "height_m": 40.0}).encode(),
        json.dumps({"down": [0, 1, 0], "valid_s": 0.0}).encode(),
        json.dumps({"down": [0, 1, 0], "tilt_deg": 10, "roll_deg": 0}).encode(),   # both forms
        json.dumps({"format": "posed.camera_mount", "version": 2, "down": [0, 1, 0]}).encode(),  # newer version
        json.dumps({"format": "posed.pose", "down": [0, 1, 0]}).encode(),
        json.dumps({"down": [0, 1, 0], "time_unix": time.time() + 3600.0}).encode(),   # a clock an hour ahead
        b'{"down": [0, 1, 0], "source": "' + b"x" * 300_000 + b'"}',           # huge
        b"[" * 100_000,                                                          # nested beyond any parser
    ]


@pytest.mark.timeout(300)
def test_garbage_on_the_key_is_counted_and_changes_nothing(tmp_path):
    rng = np.random.default_rng(7)
    got = _run(tmp_path, lambda: _garbage(rng), "falls.camera_mount_from_bus=true")
    geos = _geometries(got["status"])
    assert geos and all(g["tilt_from"] != "robot" and g["height_from"] != "robot" for g in geos)
    last = geos[-1]["robot_mount"]
    assert last["received"] == 0 and last["in_force"] is False and last["age_s"] is None
    assert 100 <= last["rejected"] <= got["put"]       # (some were put before the daemon subscribed)
    assert last["last_error"] and len(last["last_error"]) < 600 and "\n" not in last["last_error"]
    assert all(s["state"] in ("starting", "running") for s in got["status"]), {s["state"] for s in got["status"]}
    assert all(st["restarts"] == 0 for s in got["status"][-1:] for st in s["stages"].values())
    assert all(e["geometry"]["gravity"] != "robot" for e in got["events/fall"])
    warned = [line for line in got["log"] if line.get("event") == "bad_camera_mount"]
    assert 1 <= len(warned) <= 5, len(warned)                 # a handful of lines, never one per message
    assert os.path.getsize(tmp_path / "out.log") < 2_000_000
