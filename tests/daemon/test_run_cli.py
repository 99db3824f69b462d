"""``posed run`` refusing to start (exit 78, every problem listed with its fix), ``posed watch`` without a
daemon, and the systemd unit checked by systemd-analyze."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def posed(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def test_bad_config_exits_78_listing_every_problem(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("pipeline:\n  target_fps: 0\n  stuck_after_s: fast\nzenoh:\n  mode: client\n"
                   "  listen: [nonsense]\n")
    r = posed("run", "--config", str(bad))
    assert r.returncode == 78
    err = r.stderr
    assert "pipeline.target_fps: 0.0 is out of range [0.5, 60.0] Hz" in err
    assert "pipeline.stuck_after_s: 'fast' is not a number" in err
    assert "'nonsense' is not a Zenoh endpoint" in err
    assert "client mode needs at least one router or peer" in err
    assert "nothing was started" in err


def test_missing_model_names_models_fetch(tmp_path, shared_data):
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    r = posed("run", "--source", f"file:{video}", "--set", f"landmarks.models_dir={tmp_path / 'no-models'}")
    assert r.returncode == 78
    assert "posed models fetch" in r.stderr and str(tmp_path / "no-models") in r.stderr


def test_missing_source_and_zenoh_file_are_all_listed(tmp_path):
    r = posed("run", "--source", f"file:{tmp_path / 'absent.mp4'}", "--set",
              f"zenoh.config_file={tmp_path / 'absent.json5'}")
    assert r.returncode == 78
    assert f"source.path: {tmp_path / 'absent.mp4'} does not exist" in r.stderr
    assert f"zenoh.config_file: {tmp_path / 'absent.json5'} does not exist" in r.stderr
    assert "2 problem(s)" in r.stderr


def test_watch_without_a_daemon_says_how_to_connect():
    from tests.daemon.zenoh_util import free_port

    r = posed("watch", "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "0.5", timeout=30)
    assert r.returncode == 1
    assert "cannot connect" in r.stderr and "--connect" in r.stderr


def _verify(unit: Path) -> subprocess.CompletedProcess:
    return subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, timeout=60)


def test_unit_file_passes_systemd_analyze_verify(tmp_path):
    if shutil.which("systemd-analyze") is None:
        pytest.fail("systemd-analyze is missing: apt-get install systemd (deploy/bootstrap.sh installs it)")
    text = (ROOT / "deploy" / "posed.service").read_text()
    for key in ("Type=notify", "WatchdogSec=", "Restart=on-failure", "RestartPreventExitStatus=78",
                "StateDirectory=posed", "CacheDirectory=posed", "NUMBA_CACHE_DIR=/var/cache/posed/numba",
                "POSED_MODELS_DIR=/var/lib/posed/models", "ProtectSystem=strict", "SupplementaryGroups=video",
                "DeviceAllow=char-video4linux", "DeviceAllow=char-usb_device", "KillMode=mixed"):
        assert key in text, key
    assert not re.search(r"^MemoryDenyWriteExecute=yes", text, re.M), "numba needs W+X memory"
    unit = tmp_path / "posed.service"                 # the ExecStart binary must exist for verify
    unit.write_text(text.replace("/opt/posed/venv/bin/posed", str(Path(sys.executable).parent / "posed")))
    r = _verify(unit)
    assert r.returncode == 0 and r.stderr.strip() == "", r.stderr
    broken = tmp_path / "broken.service"
    broken.write_text(unit.read_text().replace("Type=notify", "Type=notifyy"))
    r = _verify(broken)
    assert "notifyy" in r.stderr                       # the check can fail
    sec = subprocess.run(["systemd-analyze", "security", "--offline=yes", str(unit)], capture_output=True,
                         text=True, timeout=60)
    m = re.search(r"Overall exposure level for posed.service: ([\d.]+)", sec.stdout)
    assert m and float(m.group(1)) <= 2.5, sec.stdout[-300:]
