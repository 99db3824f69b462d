"""A robot upgraded to this posed keeps the models folder an earlier posed fetched. Models converted by another
converter version, or from another mediapipe release's files, are intact (their hashes match their own
manifest) but are not what this posed was validated with: `posed config check` and `posed models verify` fail on
them naming the versions and the fix; `posed run` says so and watches on with them (a robot that stopped watching
at an upgrade would serve nobody); `posed models fetch` fixes the folder without a download."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.landmarks import model_pins
from posed.landmarks.convert.converter import CONVERTER_VERSION
from posed.landmarks.models import ModelOutdatedError, check_provenance, find_models, verify_models

ROOT = Path(__file__).resolve().parents[2]
EX_CONFIG = 78


def posed(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PIP_INDEX_URL": "http://127.0.0.1:9/simple", "PIP_RETRIES": "0", "PIP_TIMEOUT": "2",
           "PIP_CONFIG_FILE": os.devnull}           # no index: a fetch that tried to download would fail
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          env=env, timeout=300)


def config_check(models: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    return posed("config", "check", "--set", f"landmarks.models_dir={models}",
                 "--set", f"pipeline.state_dir={tmp_path / 'state'}")


def run_until_ready(models: Path, tmp_path: Path, shared_data: Path) -> tuple[dict, dict]:
    """A real ``posed run`` of the squat video on ``models`` until its stages are ready: its ``models_outdated``
    and ``daemon_ready`` log lines (JSON)."""
    from tests.daemon.zenoh_util import free_port

    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    log = tmp_path / "run.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{video}?loop=true",
             "--set", f"landmarks.models_dir={models}", "--set", f"pipeline.state_dir={tmp_path / 'state'}",
             "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", "--set", "logging.format=json"],
            cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None:
            lines = [json.loads(x) for x in log.read_text().splitlines() if x.startswith("{")]
            found = {x.get("event"): x for x in lines}
            if "daemon_ready" in found:
                assert "models_outdated" in found, log.read_text()
                return found["models_outdated"], found["daemon_ready"]
            time.sleep(0.5)
        raise AssertionError(f"posed run never got ready (exit {proc.poll()}):\n{log.read_text()}")
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(30)


@pytest.fixture
def earlier(models_dir, tmp_path) -> Path:
    folder = tmp_path / "models"
    shutil.copytree(models_dir, folder)
    return folder


def edit_manifest(folder: Path, **changes) -> None:
    manifest = json.loads((folder / "manifest.json").read_text())
    manifest.update(changes)
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=2))


def test_models_of_an_older_converter_are_named_the_daemon_watches_on_and_a_fetch_fixes_them_offline(
        earlier, tmp_path, shared_data):
    edit_manifest(earlier, converter_version="1")
    verify_models(find_models(earlier))             # intact
    with pytest.raises(ModelOutdatedError):
        check_provenance(find_models(earlier))
    proc = config_check(earlier, tmp_path)
    assert proc.returncode == EX_CONFIG, proc.stdout + proc.stderr
    assert "converted by converter version '1'" in proc.stderr
    assert f"runs the models of converter version '{CONVERTER_VERSION}'" in proc.stderr
    assert f"posed models fetch --models-dir {earlier}" in proc.stderr
    outdated, ready = run_until_ready(earlier, tmp_path, shared_data)
    assert "converted by converter version '1'" in outdated["problem"] and "starting anyway" in outdated["note"]
    assert ready["event"] == "daemon_ready"                            # watching on the earlier models
    fetched = posed("models", "fetch", "--models-dir", str(earlier))
    assert fetched.returncode == 0, fetched.stderr
    assert "re-converting the TFLite models kept" in fetched.stdout      # no download
    assert config_check(earlier, tmp_path).returncode == 0


def test_models_from_another_mediapipe_release_are_named_by_config_check(earlier, tmp_path):
    manifest = json.loads((earlier / "manifest.json").read_text())
    files = manifest["files"]
    files["pose_landmark_full.tflite"]["sha256"] = "0" * 64
    edit_manifest(earlier, files=files, source={"kind": "pypi", "package": "mediapipe", "version": "0.10.14",
                                                "wheel": "mediapipe-0.10.14-cp311-cp311-manylinux_2_28_x86_64.whl"})
    proc = config_check(earlier, tmp_path)
    assert proc.returncode == EX_CONFIG, proc.stdout + proc.stderr
    assert "pose_landmark_full.tflite with sha256 " + "0" * 64 in proc.stderr
    assert "mediapipe 0.10.14 from PyPI" in proc.stderr
    assert f"not from mediapipe {model_pins.MEDIAPIPE_VERSION}'s" in proc.stderr
    assert "posed models fetch" in proc.stderr
    fetched = posed("models", "fetch", "--models-dir", str(earlier))      # the kept files match the pins
    assert fetched.returncode == 0, fetched.stderr
    assert config_check(earlier, tmp_path).returncode == 0


def test_verify_says_what_the_folder_holds(earlier):
    """`posed models verify` names the converter and the mediapipe release (what a support person asks)."""
    proc = posed("models", "verify", "--models-dir", str(earlier))
    assert proc.returncode == 0, proc.stderr
    assert f"converter {CONVERTER_VERSION}, mediapipe {model_pins.MEDIAPIPE_VERSION}" in proc.stdout
    edit_manifest(earlier, converter_version="1")
    proc = posed("models", "verify", "--models-dir", str(earlier))
    assert proc.returncode == 1 and "converter version '1'" in proc.stderr
