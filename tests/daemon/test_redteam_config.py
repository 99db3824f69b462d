"""A config that cannot work is exit 78 at ``posed config check`` and at ``posed run`` start, before any stage
is spawned, with every problem listed: a missing calibration file, missing or damaged models, an unreadable
or invalid native Zenoh config, an empty hook argv, row_init > row_max, duplicate YAML keys, a file that is
not UTF-8. Real CLI processes, real model files (copied and damaged)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RECORDING = "falls/urfd_dev/urfd_18_adl.landmarks.jsonl"


def posed(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def _recording(shared_data: Path) -> Path:
    path = shared_data / RECORDING
    assert path.is_file(), f"the shared data lacks {path}"
    return path


def test_missing_calibration_is_exit_78_at_check_and_at_start_before_any_stage(tmp_path, shared_data):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"fitting:\n  calibration: {tmp_path / 'user.yaml'}\n")
    r = posed("config", "check", str(cfg))
    assert r.returncode == 78, r.stdout + r.stderr
    assert f"fitting.calibration: {tmp_path / 'user.yaml'}" in r.stderr and "posed calibrate" in r.stderr
    r = posed("run", "--config", str(cfg), "--source", f"file:{_recording(shared_data)}",
              "--set", f"pipeline.state_dir={tmp_path / 'state'}")
    assert r.returncode == 78, r.stdout + r.stderr
    assert "fitting.calibration" in r.stderr and "nothing was started" in r.stderr
    assert "stage_start" not in r.stdout and "daemon_start" not in r.stdout


def test_every_start_up_problem_is_listed_at_once(tmp_path, shared_data):
    models = tmp_path / "models"
    from posed.landmarks import find_models

    shutil.copytree(find_models(None).models_dir, models)
    with open(models / "pose_landmark_full.onnx", "r+b") as fh:          # damage one byte of a real model
        fh.seek(1000)
        b = fh.read(1)
        fh.seek(1000)
        fh.write(bytes([b[0] ^ 0xFF]))
    zenoh_cfg = tmp_path / "zenoh.json5"
    zenoh_cfg.write_text("{ mode: ")
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"""landmarks:
  models_dir: {models}
zenoh:
  config_file: {zenoh_cfg}
fitting:
  calibration: {tmp_path / 'absent.yaml'}
  row_init: 8
  row_max: 5
hooks:
  on_event:
    - argv: []
""")
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    for args in (("config", "check", str(cfg)), ("run", "--config", str(cfg), "--source", f"file:{video}")):
        r = posed(*args)
        assert r.returncode == 78, r.stdout + r.stderr
        err = r.stderr
        assert "pose_landmark_full.onnx is damaged" in err
        assert f"zenoh.config_file: {zenoh_cfg} is not a valid Zenoh config" in err
        assert "fitting.calibration" in err
        assert "fitting.row_init: 8 is more than fitting.row_max (5)" in err
        assert "hooks.on_event[0].argv is empty" in err
        assert "5 problem(s)" in err, err
        assert "stage_start" not in r.stdout


def test_unreadable_zenoh_config_file(tmp_path):
    zenoh_cfg = tmp_path / "zenoh.json5"
    zenoh_cfg.write_text("{}")
    zenoh_cfg.chmod(0)
    if os.access(zenoh_cfg, os.R_OK):            # root reads anything: make it a folder instead
        zenoh_cfg.unlink()
        zenoh_cfg.mkdir()
    r = posed("config", "check", str(ROOT / "config.yaml"), "--set", f"zenoh.config_file={zenoh_cfg}")
    assert r.returncode == 78 and f"zenoh.config_file: {zenoh_cfg}" in r.stderr, r.stderr


def test_duplicate_yaml_keys_are_errors_with_their_paths(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("robot_id: a\npipeline:\n  target_fps: 10\n  target_fps: 20\nrobot_id: b\n"
                   "fitting:\n  restarts: nonsense\n")
    r = posed("config", "check", str(cfg))
    assert r.returncode == 78
    assert "pipeline.target_fps: duplicate key (lines 3 and 4)" in r.stderr, r.stderr
    assert "robot_id: duplicate key (lines 1 and 5)" in r.stderr
    assert "fitting.restarts: 'nonsense' is not an integer" in r.stderr        # the other problems too
    assert "3 problem(s)" in r.stderr


@pytest.mark.parametrize("command", ["check", "run"])
def test_config_not_utf8_is_a_clear_exit_78(tmp_path, command):
    cfg = tmp_path / "latin1.yaml"
    cfg.write_bytes("robot_id: küche\n".encode("latin-1"))
    args = ("config", "check", str(cfg)) if command == "check" else ("run", "--config", str(cfg))
    r = posed(*args)
    assert r.returncode == 78, r.stderr
    assert "Traceback" not in r.stderr
    assert "not UTF-8" in r.stderr and "line 1" in r.stderr and "iconv" in r.stderr


def test_good_config_still_passes(tmp_path):
    r = posed("config", "check", str(ROOT / "config.yaml"))
    assert r.returncode == 0, r.stderr
