"""Where the landmark models live at run time, and whether they are intact.

``posed models fetch`` (``landmarks.convert.fetch``) writes a models folder holding MediaPipe's two
TFLite files, their ONNX conversions and ``manifest.json`` (sources, sha256 of every file, converter
version). This module only finds and checks that folder, and whether it is what this posed runs
(``check_provenance``, against ``landmarks.model_pins``); it needs nothing beyond the standard library.

Folder, first that applies: the ``--models-dir`` option / ``landmarks.models_dir`` config key (passed as
``configured``), ``$POSED_MODELS_DIR`` (the systemd unit points it at its state dir),
``$XDG_CACHE_HOME/posed/models``, ``~/.cache/posed/models``.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from posed.landmarks.model_pins import (
    CONVERTER_VERSION,
    DETECTOR_ONNX,
    DETECTOR_TFLITE,
    LANDMARK_ONNX,
    LANDMARK_TFLITE,
    MEDIAPIPE_VERSION,
    PINNED,
)

ENV_MODELS_DIR = "POSED_MODELS_DIR"
MANIFEST = "manifest.json"
MANIFEST_FORMAT = 1
MODEL_FILES = (DETECTOR_ONNX, LANDMARK_ONNX, DETECTOR_TFLITE, LANDMARK_TFLITE)
FETCH_HINT = "run `posed models fetch`"


class ModelMissingError(FileNotFoundError):
    """The models folder lacks a model (or its manifest); the message names the folder and the fix."""


class ModelCorruptError(ModelMissingError):
    """A model file differs from what its manifest records (hash or size); re-fetching fixes it."""


class ModelOutdatedError(ModelMissingError):
    """The folder is intact but not what this posed runs: converted by another converter version, or from
    TFLite files other than the pinned mediapipe release's (an earlier posed's fetch, a folder copied from
    elsewhere). ``posed models fetch`` converts the pinned files again (without a download when they are kept)."""


@dataclass(frozen=True)
class ModelPaths:
    """The files of one models folder (paths may not exist: see ``find_models``)."""

    models_dir: Path
    detector_onnx: Path
    landmark_onnx: Path
    detector_tflite: Path
    landmark_tflite: Path
    manifest: Path

    @classmethod
    def in_dir(cls, models_dir: str | os.PathLike) -> ModelPaths:
        d = Path(models_dir)
        return cls(d, d / DETECTOR_ONNX, d / LANDMARK_ONNX, d / DETECTOR_TFLITE, d / LANDMARK_TFLITE,
                   d / MANIFEST)


def default_models_dir(configured: str = "") -> Path:
    """The models folder: ``configured`` (option or config key) if set, else ``$POSED_MODELS_DIR``, else
    ``$XDG_CACHE_HOME/posed/models`` (``~/.cache/posed/models`` when XDG_CACHE_HOME is unset or relative)."""
    if configured:
        return Path(configured).expanduser()
    env = os.environ.get(ENV_MODELS_DIR, "")
    if env:
        return Path(env).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME", "")
    base = Path(cache) if cache and Path(cache).is_absolute() else Path.home() / ".cache"
    return base / "posed" / "models"


def _fetch_hint(models_dir: Path) -> str:
    return f"{FETCH_HINT} (or `posed models fetch --models-dir {models_dir}`)"


def find_models(models_dir: str | os.PathLike | None = None) -> ModelPaths:
    """The model files of ``models_dir`` (default: ``default_models_dir()``); raises ModelMissingError
    naming the folder, the missing files and ``posed models fetch`` when any file or the manifest is
    missing. Does not hash anything (see ``verify_models``)."""
    d = Path(models_dir).expanduser() if models_dir else default_models_dir()
    paths = ModelPaths.in_dir(d)
    if not d.is_dir():
        raise ModelMissingError(f"no landmark models: the models folder {d} does not exist; {_fetch_hint(d)}")
    missing = [p.name for p in (paths.detector_onnx, paths.landmark_onnx, paths.detector_tflite,
                                paths.landmark_tflite, paths.manifest) if not p.is_file()]
    if missing:
        raise ModelMissingError(f"landmark models missing in {d}: {', '.join(missing)}; {_fetch_hint(d)}")
    return paths


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def read_manifest(paths: ModelPaths) -> dict:
    """The manifest as a dict; ModelCorruptError when it is unreadable or not a posed models manifest."""
    try:
        manifest = json.loads(paths.manifest.read_text())
    except (OSError, ValueError) as exc:
        raise ModelCorruptError(f"unreadable model manifest {paths.manifest}: {exc}; "
                                f"{_fetch_hint(paths.models_dir)}") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT \
            or not isinstance(manifest.get("files"), dict):
        raise ModelCorruptError(f"{paths.manifest} is not a posed models manifest "
                                f"(format {MANIFEST_FORMAT}); "
                                f"{_fetch_hint(paths.models_dir)}")
    return manifest


def verify_models(paths: ModelPaths, include_tflite: bool = False) -> dict:
    """Check the files against ``manifest.json`` (size and sha256); returns the manifest.

    By default only the two ONNX files the daemon runs are hashed (about 25 MB, tens of ms);
    ``include_tflite`` hashes the TFLite originals too. Raises ModelCorruptError naming the file, the
    expected and the actual sha256, and ``posed models fetch``. Whether the files are what this posed runs is
    :func:`check_provenance`'s question, not this one's: an intact folder of an earlier posed still runs.
    """
    manifest = read_manifest(paths)
    names = list(MODEL_FILES if include_tflite else (DETECTOR_ONNX, LANDMARK_ONNX))
    for name in names:
        entry = manifest["files"].get(name)
        path = paths.models_dir / name
        if not isinstance(entry, dict) or "sha256" not in entry:
            raise ModelCorruptError(f"{paths.manifest} has no sha256 for {name}; "
                                    f"{_fetch_hint(paths.models_dir)}")
        # the size check sits outside the ``except FileNotFoundError``: ModelCorruptError is one too (a
        # subclass of ModelMissingError), and a truncated file must be reported as damaged, not as missing
        try:
            size = path.stat().st_size
        except FileNotFoundError as exc:
            raise ModelMissingError(f"landmark model {path} is missing; "
                                    f"{_fetch_hint(paths.models_dir)}") from exc
        if "bytes" in entry and size != entry["bytes"]:
            what = "truncated" if isinstance(entry["bytes"], int) and size < entry["bytes"] else "damaged"
            raise ModelCorruptError(f"model file {path} is {what}: {size} bytes, the manifest says "
                                    f"{entry['bytes']}; {_fetch_hint(paths.models_dir)} to fetch it again")
        try:
            got = sha256_file(path)
        except FileNotFoundError as exc:        # removed between the two calls
            raise ModelMissingError(f"landmark model {path} is missing; "
                                    f"{_fetch_hint(paths.models_dir)}") from exc
        if got != entry["sha256"]:
            raise ModelCorruptError(f"model file {path} is damaged (corrupt): sha256 {got}, the manifest expects "
                                    f"{entry['sha256']}; {_fetch_hint(paths.models_dir)} to fetch it again")
    return manifest


def _source_text(manifest: dict) -> str:
    src = manifest.get("source")
    if not isinstance(src, dict) or not src:
        return "source not recorded"
    if src.get("kind") == "pypi":
        return f"mediapipe {src.get('version', '?')} from PyPI"
    if src.get("kind") == "wheel":
        return f"the wheel {src.get('wheel', '?')}"
    return f"the folder {src.get('path', '?')}"


def check_provenance(paths: ModelPaths, manifest: dict | None = None) -> None:
    """Raise ModelOutdatedError unless the manifest says its ONNX files were made by this posed's converter
    version (``model_pins.CONVERTER_VERSION``) from the pinned TFLite files of mediapipe ``MEDIAPIPE_VERSION``:
    an upgrade of posed (a new converter) or of mediapipe (other models) must never change what runs unsaid.
    Reads nothing but the manifest (``manifest`` when already read). ``posed models verify`` and ``posed config check`` fail on it; ``posed run``
    logs it and starts (the intact models of the earlier posed watch on until someone fetches: a robot that
    stopped watching at an upgrade would serve nobody)."""
    manifest = read_manifest(paths) if manifest is None else manifest
    fix = (f"run `posed models fetch --models-dir {paths.models_dir}` (it converts the pinned TFLite files again, "
           "without a download when the folder keeps them)")
    version = manifest.get("converter_version")
    if version != CONVERTER_VERSION:
        raise ModelOutdatedError(
            f"the landmark models in {paths.models_dir} were converted by converter version {version!r} "
            f"(manifest {paths.manifest}); this posed runs the models of converter version {CONVERTER_VERSION!r}; "
            f"{fix}")
    for pin in PINNED:
        entry = manifest["files"].get(pin.name)
        got = entry.get("sha256") if isinstance(entry, dict) else None
        if got != pin.sha256:
            raise ModelOutdatedError(
                f"the landmark models in {paths.models_dir} were converted from a {pin.name} with sha256 {got} "
                f"({_source_text(manifest)}), not from mediapipe {MEDIAPIPE_VERSION}'s ({pin.sha256}), the one "
                f"this posed runs; {fix}")


def installed_models(models_dir: str | os.PathLike | None = None) -> dict:
    """What the models folder holds, from its manifest alone (nothing hashed, cheap enough for every status
    message and ``posed --version``): ``{"dir", "converter_version", "mediapipe", "detector_onnx_sha256",
    "landmark_onnx_sha256"}``, or ``{"dir", "error"}`` when there is no readable manifest."""
    d = Path(models_dir).expanduser() if models_dir else default_models_dir()
    paths = ModelPaths.in_dir(d)
    try:
        manifest = read_manifest(paths)
    except ModelMissingError as exc:
        return {"dir": str(d), "error": str(exc)}
    files = manifest["files"]
    src = manifest.get("source") if isinstance(manifest.get("source"), dict) else {}
    pinned = all((files.get(p.name) or {}).get("sha256") == p.sha256 for p in PINNED)
    return {"dir": str(d), "converter_version": str(manifest.get("converter_version", "")),
            "mediapipe": str(src.get("version") or (MEDIAPIPE_VERSION if pinned else "unknown")),
            "detector_onnx_sha256": str((files.get(DETECTOR_ONNX) or {}).get("sha256", "")),
            "landmark_onnx_sha256": str((files.get(LANDMARK_ONNX) or {}).get("sha256", ""))}


def describe_models(models: dict) -> str:
    """:func:`installed_models` as one line for a support person: ``converter 2, mediapipe 0.10.21
    (pose_detection.onnx ad88d436b6a9, pose_landmark_full.onnx 4181150f1d07) in DIR``, or why there are none."""
    if "error" in models:
        return f"none usable in {models['dir']} ({models['error']})"
    return (f"converter {models['converter_version']}, mediapipe {models['mediapipe']} (pose_detection.onnx "
            f"{models['detector_onnx_sha256'][:12]}, pose_landmark_full.onnx {models['landmark_onnx_sha256'][:12]}) "
            f"in {models['dir']}")
