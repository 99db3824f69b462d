"""Finding and checking the models folder (landmarks.models) and `posed models fetch` (landmarks.convert.fetch):
offline installs from a wheel or a folder, idempotence, and the error messages."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from posed.cli import main
from posed.landmarks.convert.converter import CONVERTER_VERSION
from posed.landmarks.convert.fetch import PINNED, FetchError, fetch_models, up_to_date
from posed.landmarks.convert.fetch_errors import write_error
from posed.landmarks.models import (
    ENV_MODELS_DIR,
    MODEL_FILES,
    ModelCorruptError,
    ModelMissingError,
    ModelPaths,
    default_models_dir,
    find_models,
    verify_models,
)

ROOT = Path(__file__).resolve().parents[2]
PIN = {p.name: p for p in PINNED}


@pytest.fixture(scope="module")
def tflite_folder(models_dir, tmp_path_factory) -> Path:
    """A folder holding only the two original TFLite files (what `--from DIR` takes)."""
    folder = tmp_path_factory.mktemp("tflite")
    for pin in PINNED:
        shutil.copy(models_dir / pin.name, folder / pin.name)
    return folder


@pytest.fixture(scope="module")
def fetched(tflite_folder, tmp_path_factory) -> Path:
    """A models folder made by fetch_models from the TFLite folder (shared by the read-only checks)."""
    target = tmp_path_factory.mktemp("fetched") / "models"
    fetch_models(target, source=tflite_folder)
    return target


def copy_of(folder: Path, tmp_path: Path) -> Path:
    target = tmp_path / "models"
    shutil.copytree(folder, target)
    return target


def offline_env(monkeypatch) -> None:
    """pip pointed at a closed local port: any download attempt fails fast."""
    monkeypatch.setenv("PIP_INDEX_URL", "http://127.0.0.1:9/simple")
    monkeypatch.setenv("PIP_RETRIES", "0")
    monkeypatch.setenv("PIP_TIMEOUT", "2")
    monkeypatch.setenv("PIP_CONFIG_FILE", os.devnull)
    monkeypatch.delenv("PIP_FIND_LINKS", raising=False)
    monkeypatch.delenv("PIP_EXTRA_INDEX_URL", raising=False)


# ---- where the folder is --------------------------------------------------------------------------------
def test_default_dir_precedence(monkeypatch, tmp_path):
    monkeypatch.delenv(ENV_MODELS_DIR, raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_models_dir() == tmp_path / "home" / ".cache" / "posed" / "models"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")  # the XDG spec: relative paths are invalid
    assert default_models_dir() == tmp_path / "home" / ".cache" / "posed" / "models"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert default_models_dir() == tmp_path / "cache" / "posed" / "models"
    monkeypatch.setenv(ENV_MODELS_DIR, str(tmp_path / "state" / "models"))
    assert default_models_dir() == tmp_path / "state" / "models"
    assert default_models_dir(str(tmp_path / "configured")) == tmp_path / "configured"
    assert default_models_dir("~/m") == tmp_path / "home" / "m"


def test_missing_folder_names_it_and_the_fix(tmp_path):
    with pytest.raises(ModelMissingError) as err:
        find_models(tmp_path / "nowhere")
    assert str(tmp_path / "nowhere") in str(err.value) and "posed models fetch" in str(err.value)


def test_missing_file_names_it(fetched, tmp_path):
    folder = copy_of(fetched, tmp_path)
    (folder / "pose_landmark_full.onnx").unlink()
    with pytest.raises(ModelMissingError) as err:
        find_models(folder)
    msg = str(err.value)
    assert "pose_landmark_full.onnx" in msg and str(folder) in msg and "posed models fetch" in msg
    assert "pose_detection.onnx" not in msg


def test_find_models_paths(fetched):
    paths = find_models(fetched)
    assert paths == ModelPaths.in_dir(fetched)
    assert paths.detector_onnx.name == "pose_detection.onnx" and paths.landmark_tflite.is_file()


# ---- verifying ------------------------------------------------------------------------------------------
def test_verify_is_cheap_and_passes(fetched, monkeypatch):
    # cheap by construction rather than by a clock: it hashes the two ONNX files the daemon runs, once each,
    # and nothing else (its speed is in docs/models.md)
    import posed.landmarks.models as models

    hashed = []
    real = models.sha256_file

    def counting(path, *args, **kw):
        hashed.append(Path(path).name)
        return real(path, *args, **kw)

    monkeypatch.setattr(models, "sha256_file", counting)
    paths = find_models(fetched)
    manifest = verify_models(paths)
    assert sorted(hashed) == ["pose_detection.onnx", "pose_landmark_full.onnx"]
    assert manifest["converter_version"] == CONVERTER_VERSION
    verify_models(paths, include_tflite=True)


def test_verify_names_damaged_file_and_both_hashes(fetched, tmp_path):
    folder = copy_of(fetched, tmp_path)
    onnx_path = folder / "pose_detection.onnx"
    data = bytearray(onnx_path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    onnx_path.write_bytes(bytes(data))
    expected = json.loads((folder / "manifest.json").read_text())["files"]["pose_detection.onnx"]["sha256"]
    with pytest.raises(ModelCorruptError) as err:
        verify_models(find_models(folder))
    msg = str(err.value)
    assert str(onnx_path) in msg and expected in msg and hashlib.sha256(data).hexdigest() in msg
    assert "posed models fetch" in msg


def test_verify_checks_tflite_only_when_asked(fetched, tmp_path):
    folder = copy_of(fetched, tmp_path)
    with open(folder / "pose_detection.tflite", "r+b") as f:
        f.seek(100)
        f.write(b"\0\0\0\0")
    verify_models(find_models(folder))  # the daemon only runs the ONNX files
    with pytest.raises(ModelCorruptError, match="pose_detection.tflite"):
        verify_models(find_models(folder), include_tflite=True)


@pytest.mark.parametrize("content", ["{not json", '{"format": 99, "files": {}}', "[]"])
def test_bad_manifest(fetched, tmp_path, content):
    folder = copy_of(fetched, tmp_path)
    (folder / "manifest.json").write_text(content)
    with pytest.raises(ModelCorruptError, match="posed models fetch"):
        verify_models(find_models(folder))


# ---- fetching -------------------------------------------------------------------------------------------
def test_fetch_from_folder_writes_everything_then_does_nothing(fetched, tflite_folder):
    manifest = json.loads((fetched / "manifest.json").read_text())
    assert manifest["source"] == {"kind": "folder", "path": str(tflite_folder.resolve())}
    assert manifest["converter_version"] == CONVERTER_VERSION and manifest["format"] == 1
    assert manifest["created"].endswith("+00:00")
    for name in MODEL_FILES:
        data = (fetched / name).read_bytes()
        assert manifest["files"][name] == {**manifest["files"][name], "sha256": hashlib.sha256(data).hexdigest(),
                                           "bytes": len(data)}
    for pin in PINNED:
        assert manifest["files"][pin.name]["sha256"] == pin.sha256
    before = {p.name: p.stat().st_mtime_ns for p in fetched.iterdir()}
    result = fetch_models(fetched)
    # nothing done: only the up-to-date check ran (no obtain, convert or write step), no file was touched
    assert not result.changed and set(result.seconds) == {"check"}
    assert {p.name: p.stat().st_mtime_ns for p in fetched.iterdir()} == before
    assert sorted(p.name for p in fetched.iterdir()) == sorted([*MODEL_FILES, "manifest.json"])


def test_fetch_from_wheel_and_from_a_folder_holding_it(models_dir, tmp_path, monkeypatch):
    offline_env(monkeypatch)
    wheel = tmp_path / "dl" / "mediapipe-0.10.21-cp312-cp312-macosx_11_0_universal2.whl"
    wheel.parent.mkdir()
    with zipfile.ZipFile(wheel, "w") as z:
        z.writestr("mediapipe/__init__.py", "")
        for pin in PINNED:
            z.write(models_dir / pin.name, pin.member)
    result = fetch_models(tmp_path / "a", source=wheel)
    assert result.changed
    src = result.manifest["source"]
    assert src["kind"] == "wheel" and src["wheel"] == wheel.name
    assert src["wheel_sha256"] == hashlib.sha256(wheel.read_bytes()).hexdigest()
    verify_models(find_models(tmp_path / "a"), include_tflite=True)
    result = fetch_models(tmp_path / "b", source=wheel.parent)
    assert result.manifest["source"]["kind"] == "wheel"
    onnx_a = (tmp_path / "a" / "pose_detection.onnx").read_bytes()
    assert (tmp_path / "b" / "pose_detection.onnx").read_bytes() == onnx_a
    with zipfile.ZipFile(wheel) as z:  # an unpacked wheel: files under mediapipe/modules/...
        z.extractall(tmp_path / "unpacked")
    result = fetch_models(tmp_path / "c", source=tmp_path / "unpacked")
    assert result.manifest["source"]["kind"] == "folder"
    assert (tmp_path / "c" / "pose_detection.onnx").read_bytes() == onnx_a
    assert not fetch_models(tmp_path / "c", source=wheel).changed  # up to date whatever the source


def test_fetch_reconverts_from_kept_tflite_without_network(fetched, tmp_path, monkeypatch):
    offline_env(monkeypatch)
    folder = copy_of(fetched, tmp_path)
    (folder / "pose_landmark_full.onnx").write_bytes(b"garbage")
    result = fetch_models(folder)
    assert result.changed
    assert result.manifest["source"] == json.loads((fetched / "manifest.json").read_text())["source"]
    verify_models(find_models(folder), include_tflite=True)
    assert (folder / "pose_landmark_full.onnx").read_bytes() == (fetched / "pose_landmark_full.onnx").read_bytes()


def test_a_folder_from_an_older_converter_is_converted_again_offline(fetched, tmp_path, monkeypatch):
    """Converter 1 shipped the landmark model with its segmentation head: such a folder is out of date and
    the next fetch re-converts the kept TFLite files without a download."""
    offline_env(monkeypatch)
    folder = copy_of(fetched, tmp_path)
    manifest = json.loads((folder / "manifest.json").read_text())
    manifest["converter_version"] = "1"
    (folder / "manifest.json").write_text(json.dumps(manifest))
    assert up_to_date(find_models(folder)) is None
    result = fetch_models(folder)
    assert result.changed and result.manifest["converter_version"] == CONVERTER_VERSION
    assert result.manifest["files"]["pose_landmark_full.onnx"]["outputs"] == [
        "Identity", "Identity_1", "Identity_3", "Identity_4"]
    assert (folder / "pose_landmark_full.onnx").read_bytes() == (fetched / "pose_landmark_full.onnx").read_bytes()


def test_offline_download_failure_names_from(tmp_path, monkeypatch):
    offline_env(monkeypatch)
    t = time.perf_counter()
    with pytest.raises(FetchError) as err:
        fetch_models(tmp_path / "models")
    assert time.perf_counter() - t < 60
    assert "--from" in str(err.value) and "mediapipe==0.10.21" in str(err.value)
    assert err.value.exit_code == 69
    assert not (tmp_path / "models" / "manifest.json").exists()


def test_hash_mismatch_names_file_expected_and_got(tflite_folder, tmp_path):
    folder = tmp_path / "src"
    shutil.copytree(tflite_folder, folder)
    data = bytearray((folder / "pose_landmark_full.tflite").read_bytes())
    data[-10] ^= 1
    (folder / "pose_landmark_full.tflite").write_bytes(bytes(data))
    with pytest.raises(FetchError) as err:
        fetch_models(tmp_path / "models", source=folder)
    msg = str(err.value)
    assert "pose_landmark_full.tflite" in msg and PIN["pose_landmark_full.tflite"].sha256 in msg
    assert hashlib.sha256(data).hexdigest() in msg and err.value.exit_code == 65
    assert not (tmp_path / "models" / "manifest.json").exists()


@pytest.mark.parametrize("kind", ["not_zip", "truncated", "no_members"])
def test_bad_wheel(models_dir, tmp_path, kind):
    wheel = tmp_path / "mediapipe-0.10.21-cp311-cp311-manylinux_2_28_x86_64.whl"
    with zipfile.ZipFile(wheel, "w") as z:
        z.writestr("mediapipe/__init__.py", "")
        if kind != "no_members":
            for pin in PINNED:
                z.write(models_dir / pin.name, pin.member)
    if kind == "not_zip":
        wheel.write_bytes(b"<html>proxy error</html>")
    elif kind == "truncated":
        wheel.write_bytes(wheel.read_bytes()[: wheel.stat().st_size // 2])
    with pytest.raises(FetchError) as err:
        fetch_models(tmp_path / "models", source=wheel)
    assert str(wheel) in str(err.value)
    if kind == "no_members":
        assert "mediapipe/modules/pose_detection/pose_detection.tflite" in str(err.value)


def test_from_path_that_is_not_there_or_empty(tmp_path):
    with pytest.raises(FetchError, match="no such file or folder"):
        fetch_models(tmp_path / "m", source=tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FetchError, match="pose_detection.tflite"):
        fetch_models(tmp_path / "m", source=tmp_path / "empty")


def test_unwritable_target(tflite_folder, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(FetchError, match=str(blocker)):
        fetch_models(blocker / "models", source=tflite_folder)


@pytest.mark.parametrize("code, words", [(errno.ENOSPC, "no space left"), (errno.EACCES, "--models-dir"),
                                         (errno.EROFS, "POSED_MODELS_DIR"), (errno.EIO, "cannot write")])
def test_write_errors_say_what_to_do(tmp_path, code, words):
    err = write_error(tmp_path / "x.onnx", OSError(code, os.strerror(code)))
    assert words in str(err) and str(tmp_path / "x.onnx") in str(err)


# ---- the command ----------------------------------------------------------------------------------------
def test_cli_fetch_verify_where(tflite_folder, tmp_path, monkeypatch, capsys):
    target = tmp_path / "models"
    assert main(["models", "fetch", "--models-dir", str(target), "--from", str(tflite_folder)]) == 0
    out = capsys.readouterr().out
    assert f"ready in {target}" in out and PIN["pose_detection.tflite"].sha256 in out
    assert main(["models", "fetch", "--models-dir", str(target)]) == 0
    assert "up to date" in capsys.readouterr().out
    assert main(["models", "verify", "--models-dir", str(target)]) == 0
    monkeypatch.setenv(ENV_MODELS_DIR, str(target))
    assert main(["models", "where"]) == 0
    assert capsys.readouterr().out.strip().endswith(str(target))
    assert main(["models", "where", "--set", f"landmarks.models_dir={tmp_path / 'cfg'}"]) == 0
    assert capsys.readouterr().out.strip().endswith(str(tmp_path / "cfg"))
    (target / "pose_detection.onnx").write_bytes(b"x")
    assert main(["models", "verify"]) == 1
    assert "posed models fetch" in capsys.readouterr().err
    bad = tmp_path / "bad"
    shutil.copytree(tflite_folder, bad)
    (bad / "pose_detection.tflite").write_bytes(b"TFL3")
    assert main(["models", "fetch", "--models-dir", str(tmp_path / "m2"), "--from", str(bad)]) == 65
    assert "sha256 mismatch" in capsys.readouterr().err


def test_second_fetch_of_the_real_folder_is_fast(models_dir):
    """What `make test` runs before the tests: `posed models fetch` on an intact folder, in a new process.
    Fast by what it does, not by a clock (the times are in docs/models.md; a wall-clock bound here measured
    the machine's load): it finds the folder up to date and does nothing else, no download, conversion or
    write (test_fetch_from_folder_writes_everything_then_does_nothing checks the steps in-process)."""
    before = {p.name: p.stat().st_mtime_ns for p in models_dir.iterdir()}
    proc = subprocess.run([sys.executable, "-m", "posed.cli", "models", "fetch", "--models-dir", str(models_dir)],
                          capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "up to date" in proc.stdout and "nothing to do" in proc.stdout
    assert {p.name: p.stat().st_mtime_ns for p in models_dir.iterdir()} == before


def test_force_converts_again(fetched, tmp_path, monkeypatch):
    offline_env(monkeypatch)
    folder = copy_of(fetched, tmp_path)
    result = fetch_models(folder, force=True)
    assert result.changed and result.seconds["total"] > 0
    verify_models(find_models(folder), include_tflite=True)
