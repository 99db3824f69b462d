"""`posed models fetch` downloading from a package index that misbehaves: real pip against a real HTTP index on
127.0.0.1 (PIP_INDEX_URL) serving a mediapipe 0.10.21 wheel built from the real pinned TFLite files. A newer
mediapipe on the index changes nothing; an index without the wheel, a connection cut mid-download, a damaged
download and a wheel with other models each end in an error that says which, and the fix; the folder that
worked before is left as it was."""

from __future__ import annotations

import base64
import hashlib
import http.server
import os
import shutil
import subprocess
import sys
import threading
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from posed.landmarks.model_pins import PINNED
from posed.landmarks.models import find_models, verify_models

ROOT = Path(__file__).resolve().parents[2]
WHEEL = "mediapipe-{version}-cp311-cp311-{platform}.whl"


def build_wheel(folder: Path, version: str, tflite: dict[str, bytes], platform: str = "manylinux_2_28_x86_64") -> Path:
    """A mediapipe wheel pip accepts (dist-info with METADATA, WHEEL, RECORD) holding ``tflite`` at the
    members the real one has."""
    members = {"mediapipe/__init__.py": b""}
    members.update({pin.member: tflite[pin.name] for pin in PINNED})
    info = f"mediapipe-{version}.dist-info"
    members[f"{info}/METADATA"] = f"Metadata-Version: 2.1\nName: mediapipe\nVersion: {version}\n".encode()
    members[f"{info}/WHEEL"] = (f"Wheel-Version: 1.0\nGenerator: posed-tests\nRoot-Is-Purelib: false\n"
                                f"Tag: cp311-cp311-{platform}\n").encode()
    record = [f"{name},sha256={base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b'=').decode()},"
              f"{len(data)}" for name, data in members.items()]
    members[f"{info}/RECORD"] = ("\n".join([*record, f"{info}/RECORD,,"]) + "\n").encode()
    path = folder / WHEEL.format(version=version, platform=platform)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


@dataclass
class Index:
    """What the local index serves: ``wheels`` listed on /simple/mediapipe/ (with their sha256 in the link,
    as PyPI gives it, when ``hashes``), and how a download goes: ``whole``, ``cut`` (the connection closed
    after a third of the bytes) or ``half`` (half the bytes, as if a proxy cut the file)."""

    wheels: list[Path]
    download: str = "whole"
    hashes: bool = True
    url: str = ""


@pytest.fixture
def index():
    state = Index([])

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def _send(self, body: bytes, length: int | None = None, kind: str = "application/octet-stream"):
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body) if length is None else length))
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self):
            if self.path.rstrip("/") == "/simple/mediapipe":
                links = "".join(
                    f'<a href="/files/{w.name}'
                    f'{"#sha256=" + hashlib.sha256(w.read_bytes()).hexdigest() if state.hashes else ""}">'
                    f"{w.name}</a>\n" for w in state.wheels)
                self._send(f"<html><body>{links}</body></html>".encode(), kind="text/html")
                return
            wheel = next((w for w in state.wheels if self.path == f"/files/{w.name}"), None)
            if wheel is None:
                self.send_response(404)
                self.end_headers()
                return
            data = wheel.read_bytes()
            if state.download == "cut":
                self._send(data[: len(data) // 3], length=len(data))
                self.wfile.flush()
                self.connection.shutdown(2)
            elif state.download == "half":
                self._send(data[: len(data) // 2])
            else:
                self._send(data)

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    state.url = f"http://127.0.0.1:{server.server_address[1]}/simple"
    yield state
    server.shutdown()
    server.server_close()
    thread.join()


@pytest.fixture
def real_tflite(models_dir) -> dict[str, bytes]:
    return {pin.name: (models_dir / pin.name).read_bytes() for pin in PINNED}


@pytest.fixture
def working(models_dir, tmp_path) -> Path:
    """A models folder the daemon runs (a copy of the real one) whose kept TFLite files have rotted, so that the
    next fetch must download: what a failed download must leave as it was."""
    folder = tmp_path / "models"
    shutil.copytree(models_dir, folder)
    (folder / "pose_landmark_full.tflite").write_bytes(b"TFL3 rotted")
    verify_models(find_models(folder))          # the daemon's check: the ONNX files it runs are intact
    return folder


def fetch(index: Index, models: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    """`posed models fetch` as a deployer runs it, pip pointed at the local index (no other network)."""
    env = {**os.environ, "PIP_INDEX_URL": index.url, "PIP_RETRIES": "0", "PIP_TIMEOUT": "10",
           "PIP_CONFIG_FILE": os.devnull, "PIP_NO_CACHE_DIR": "1", "PIP_RESUME_RETRIES": "1",
           "TMPDIR": str(tmp_path)}
    for name in ("PIP_FIND_LINKS", "PIP_EXTRA_INDEX_URL", "PIP_NO_INDEX"):
        env.pop(name, None)
    return subprocess.run([sys.executable, "-m", "posed.cli", "models", "fetch", "--models-dir", str(models)],
                          capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)


def unchanged(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_a_newer_mediapipe_on_the_index_changes_nothing(index, real_tflite, tmp_path):
    """Guard: a newer release with other models is listed too; the fetch takes 0.10.21 and its pinned files."""
    other = {name: data[:-4] + b"NEW!" for name, data in real_tflite.items()}
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite),
                    build_wheel(tmp_path / "dl", "0.10.99", other)]
    proc = fetch(index, tmp_path / "models", tmp_path)
    assert proc.returncode == 0, proc.stderr
    manifest = verify_models(find_models(tmp_path / "models"), include_tflite=True)
    assert manifest["source"]["version"] == "0.10.21"
    assert manifest["source"]["wheel"] == index.wheels[0].name
    assert all(manifest["files"][pin.name]["sha256"] == pin.sha256 for pin in PINNED)


def test_no_wheel_for_the_platform_says_so(index, real_tflite, working, tmp_path):
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite, platform="win_amd64")]
    before = unchanged(working)
    proc = fetch(index, working, tmp_path)
    assert proc.returncode == 69, proc.stderr
    assert "has no mediapipe 0.10.21 wheel for manylinux_2_28_x86_64, CPython 3.11" in proc.stderr
    assert index.url in proc.stderr and "--from DIR" in proc.stderr
    assert unchanged(working) == before


def test_a_connection_cut_mid_download_says_the_network_failed(index, real_tflite, working, tmp_path):
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite)]
    index.download = "cut"
    before = unchanged(working)
    proc = fetch(index, working, tmp_path)
    assert proc.returncode == 69, proc.stderr
    assert "the network failed during the download of mediapipe==0.10.21" in proc.stderr
    assert "not enough bytes" in proc.stderr          # pip's own words, not only its hints
    assert "run the fetch again" in proc.stderr and "--from DIR" in proc.stderr
    assert unchanged(working) == before
    verify_models(find_models(working))


def test_a_damaged_download_is_named_damaged_not_offline(index, real_tflite, working, tmp_path):
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite)]
    index.download = "half"
    before = unchanged(working)
    proc = fetch(index, working, tmp_path)
    assert proc.returncode == 65, proc.stderr
    assert "the downloaded mediapipe 0.10.21 wheel is damaged" in proc.stderr and "Offline?" not in proc.stderr
    assert "Expected sha256" in proc.stderr and "--from" in proc.stderr
    assert unchanged(working) == before


def test_a_truncated_download_without_a_hash_is_named_damaged(index, real_tflite, working, tmp_path):
    """An index that gives no sha256 (a plain mirror): pip takes the cut file, then cannot read it."""
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite)]
    index.download, index.hashes = "half", False
    before = unchanged(working)
    proc = fetch(index, working, tmp_path)
    assert proc.returncode == 65, proc.stderr
    assert "the downloaded mediapipe 0.10.21 wheel is damaged" in proc.stderr
    assert unchanged(working) == before


def test_a_wheel_with_other_models_is_refused_by_the_pins(index, real_tflite, working, tmp_path):
    """Guard: the right name and version, other model bytes (a tampering mirror): the pins refuse it."""
    other = dict(real_tflite, **{"pose_detection.tflite": real_tflite["pose_detection.tflite"][:-4] + b"EVIL"})
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", other)]
    before = unchanged(working)
    proc = fetch(index, working, tmp_path)
    assert proc.returncode == 65, proc.stderr
    assert "pose_detection.tflite" in proc.stderr and "sha256 mismatch" in proc.stderr
    assert PINNED[0].sha256 in proc.stderr
    assert unchanged(working) == before


def test_no_room_for_the_download_says_where(index, real_tflite, working, tmp_path, tmpfs):
    """pip downloads into TMPDIR: a full one is named, with the fix, not taken for a network failure."""
    (tmp_path / "dl").mkdir()
    index.wheels = [build_wheel(tmp_path / "dl", "0.10.21", real_tflite)]
    tiny = tmpfs("1m")
    before = unchanged(working)
    proc = fetch(index, working, tiny)
    assert proc.returncode == 73, proc.stderr
    assert f"no space left for the download of mediapipe==0.10.21 (about 36 MB) in {tiny}" in proc.stderr
    assert "No space left on device" in proc.stderr and "TMPDIR" in proc.stderr
    assert unchanged(working) == before
