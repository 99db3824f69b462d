"""``posed models fetch``: get MediaPipe's pose models, check them, convert them to ONNX, write the folder.

The two TFLite files come from the ``mediapipe==0.10.21`` wheel on PyPI (the last release that ships
them; newer wheels do not) or from ``--from PATH`` (that wheel, or a folder holding the two files). Both
are pinned by sha256 (``landmarks.model_pins``). The folder then holds the TFLite originals, their ONNX
conversions and ``manifest.json``; a second run with everything intact does nothing. The download and what its
failures mean: ``fetch_pip``; the errors: ``fetch_errors``. The folder is replaced all or nothing
(:func:`_replace_all`): a fetch that fails leaves the models that worked as they were.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import re
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from posed.landmarks.convert.converter import CONVERTER_VERSION, OPSET, convert
from posed.landmarks.convert.fetch_errors import (
    EX_DATAERR,
    EX_IOERR,
    EX_SOFTWARE,
    FetchError,
    is_read_only,
    write_error,
)
from posed.landmarks.convert.fetch_pip import pip_download
from posed.landmarks.convert.tflite_graph import read_graph
from posed.landmarks.model_pins import MEDIAPIPE_VERSION, PINNED, WHEEL_NAME
from posed.landmarks.models import (
    DETECTOR_ONNX,
    DETECTOR_TFLITE,
    LANDMARK_ONNX,
    LANDMARK_TFLITE,
    MANIFEST,
    MANIFEST_FORMAT,
    ModelMissingError,
    ModelPaths,
    check_provenance,
    read_manifest,
    sha256_file,
    verify_models,
)


@dataclass(frozen=True)
class FetchResult:
    models_dir: Path
    changed: bool  # False: everything was already in place
    manifest: dict
    seconds: dict[str, float] = field(default_factory=dict)  # time per step
    removed_temporaries: tuple[str, ...] = ()  # names of files an interrupted fetch had left (removed now)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


# ---- getting the TFLite bytes ---------------------------------------------------------------------------
def _read_wheel(wheel: Path) -> dict[str, bytes]:
    out = {}
    try:
        with zipfile.ZipFile(wheel) as z:
            names = set(z.namelist())
            for pin in PINNED:
                if pin.member not in names:
                    raise FetchError(f"{wheel} lacks {pin.member}: use the mediapipe "
                                     f"{MEDIAPIPE_VERSION} wheel "
                                     "(newer mediapipe wheels no longer ship the pose models)", EX_DATAERR)
                out[pin.name] = z.read(pin.member)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError) as exc:
        raise FetchError(f"{wheel} is not a readable wheel (zip) file: {exc}; download it again",
                         EX_DATAERR) from exc
    except OSError as exc:
        raise FetchError(f"cannot read {wheel}: {exc}", EX_IOERR) from exc
    return out


def _from_path(path: Path) -> tuple[dict[str, bytes], dict]:
    """TFLite bytes from ``--from PATH`` (a wheel, or a folder with the two files or with the wheel)."""
    if not path.exists():
        raise FetchError(f"--from {path}: no such file or folder", EX_DATAERR)
    if path.is_file():
        return _read_wheel(path), {"kind": "wheel", "path": str(path.resolve()), "wheel": path.name,
                                   "wheel_sha256": sha256_file(path)}
    found = {}
    for pin in PINNED:
        for candidate in (path / pin.name, path / pin.member):
            if candidate.is_file():
                found[pin.name] = candidate
                break
    if len(found) == len(PINNED):
        try:
            data = {name: p.read_bytes() for name, p in found.items()}
        except OSError as exc:
            raise FetchError(f"cannot read the models in {path}: {exc}", EX_IOERR) from exc
        return data, {"kind": "folder", "path": str(path.resolve())}
    wheels = sorted(path.glob(f"mediapipe-{MEDIAPIPE_VERSION}-*.whl"))
    if wheels:
        return _from_path(wheels[0])
    missing = [pin.name for pin in PINNED if pin.name not in found]
    raise FetchError(f"--from {path}: the folder holds neither {' nor '.join(missing)} nor a "
                     f"mediapipe-{MEDIAPIPE_VERSION}-*.whl", EX_DATAERR)


def _download(say: Callable[[str], None]) -> tuple[dict[str, bytes], dict]:
    say(f"downloading mediapipe=={MEDIAPIPE_VERSION} ({WHEEL_NAME}, about 36 MB) from PyPI with pip")
    with tempfile.TemporaryDirectory(prefix="posed-models-") as tmp:
        wheel = pip_download(Path(tmp))
        return _read_wheel(wheel), {"kind": "pypi", "package": "mediapipe", "version": MEDIAPIPE_VERSION,
                                    "wheel": wheel.name, "wheel_sha256": sha256_file(wheel)}


def _check_pins(data: dict[str, bytes], origin: str) -> None:
    for pin in PINNED:
        got = _sha256(data[pin.name])
        if got != pin.sha256:
            raise FetchError(f"{pin.name} from {origin}: sha256 mismatch: expected {pin.sha256}, got {got} "
                             f"({len(data[pin.name])} bytes, expected {pin.size}); this is not the file of "
                             f"mediapipe {MEDIAPIPE_VERSION} (damaged download or another version)",
                             EX_DATAERR)


# ---- the folder -----------------------------------------------------------------------------------------
# The temporary name of each file the fetch writes: ``.<file>.tmp<pid of the writer>`` (:func:`_stage`).
OWN_FILES = (DETECTOR_TFLITE, LANDMARK_TFLITE, DETECTOR_ONNX, LANDMARK_ONNX, MANIFEST)
_TEMPORARY = re.compile(r"\.(" + "|".join(re.escape(n) for n in OWN_FILES) + r")\.tmp([0-9]+)")
# A temporary is written and renamed within seconds; one this old is stale whatever its writer's pid now is.
STALE_AFTER_S = 600.0


def _temporary(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp{os.getpid()}")


def stale_temporaries(models_dir: Path) -> list[Path]:
    """The fetch's own temporaries (``.<model file>.tmp<pid>``) in ``models_dir`` left by a fetch that was
    killed (kill -9, a power cut) before it renamed them: their writer is gone (or they are older than
    ``STALE_AFTER_S``, so the pid was reused). Another fetch's temporaries while it runs are not among them;
    nor is any other file."""
    found = []
    try:
        entries = list(os.scandir(models_dir))
    except OSError:
        return found
    now = time.time()
    for entry in entries:
        m = _TEMPORARY.fullmatch(entry.name)
        if not m or not entry.is_file(follow_symlinks=False):
            continue
        pid = int(m.group(2))
        try:
            age = now - entry.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        if pid == os.getpid() or (_alive(pid) and age < STALE_AFTER_S):
            continue
        found.append(Path(entry.path))
    return sorted(found)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def remove_stale_temporaries(models_dir: Path, say: Callable[[str], None]) -> tuple[str, ...]:
    """Remove :func:`stale_temporaries` and say so (how many, their names and bytes); their names."""
    removed, total, failed = [], 0, []
    for path in stale_temporaries(models_dir):
        try:
            size = path.stat().st_size
            path.unlink()
        except FileNotFoundError:
            continue
        except OSError as exc:
            failed.append(f"{path.name} ({exc.strerror})")
            continue
        removed.append(path.name)
        total += size
    if removed:
        say(f"removed {len(removed)} temporary file(s) left in {models_dir} by an interrupted fetch "
            f"({total / 1e6:.1f} MB): {', '.join(removed)}")
    if failed:
        say(f"could not remove temporary file(s) left by an interrupted fetch: {', '.join(failed)}")
    return tuple(removed)


def _stage(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path``'s temporary name and fsync it; the temporary (``path`` is not touched)."""
    tmp = _temporary(path)
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise write_error(path, exc) from exc
    return tmp


def _replace_all(models_dir: Path, files: dict[str, bytes]) -> None:
    """Put ``files`` (name -> bytes, the manifest among them) in ``models_dir`` all or nothing: every file is
    first written beside the old ones under its temporary name, so a full disk, a read-only or vanished
    folder or an I/O error leaves the folder as it was (the models that worked keep working, their manifest
    still vouching for them). Only then the manifest goes, the files are renamed over the old ones and the new
    manifest comes last: a crash in these renames leaves a folder that reads as missing, never as valid."""
    staged: dict[str, Path] = {}
    try:
        for name, data in files.items():
            staged[name] = _stage(models_dir / name, data)
    except FetchError:
        for tmp in staged.values():
            tmp.unlink(missing_ok=True)
        raise
    order = [name for name in files if name != MANIFEST] + [MANIFEST]
    try:
        (models_dir / MANIFEST).unlink(missing_ok=True)  # no manifest = incomplete while files change
        for name in order:
            os.replace(staged[name], models_dir / name)
        dir_fd = os.open(models_dir, os.O_RDONLY)
        try:
            os.fsync(dir_fd)        # the renames themselves on disk
        finally:
            os.close(dir_fd)
    except OSError as exc:
        for tmp in staged.values():
            tmp.unlink(missing_ok=True)
        raise write_error(models_dir, exc) from exc


def up_to_date(paths: ModelPaths) -> dict | None:
    """The manifest when the folder is complete, made by this converter version from the pinned TFLite
    files, and every file matches its recorded size and sha256; else None."""
    try:
        manifest = verify_models(paths, include_tflite=True)    # every file, then the converter version and pins
        check_provenance(paths, manifest)
    except ModelMissingError:                                    # ModelCorruptError, ModelOutdatedError alike
        return None
    return manifest


def _kept_tflite(paths: ModelPaths) -> tuple[dict[str, bytes], dict] | None:
    """The TFLite files already in the folder when both match their pins (no download needed)."""
    data = {}
    for pin in PINNED:
        p = paths.models_dir / pin.name
        if not p.is_file() or p.stat().st_size != pin.size:
            return None
        data[pin.name] = p.read_bytes()
        if _sha256(data[pin.name]) != pin.sha256:
            return None
    try:
        source = read_manifest(paths).get("source") or {}
    except ModelMissingError:
        source = {}
    return data, source or {"kind": "folder", "path": str(paths.models_dir.resolve())}


def _smoke_test(name: str, onnx_bytes: bytes, tflite_bytes: bytes, outputs: tuple[str, ...] | None) -> None:
    """Load the converted model in onnxruntime and check its outputs' names and shapes on zeros."""
    import onnxruntime as ort

    graph = read_graph(tflite_bytes)
    want = {graph.tensors[i].name: graph.tensors[i].shape for i in graph.outputs
            if outputs is None or graph.tensors[i].name in outputs}
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    sess = ort.InferenceSession(onnx_bytes, opts, providers=["CPUExecutionProvider"])
    inp = sess.get_inputs()[0]
    outs = sess.run(None, {inp.name: np.zeros(inp.shape, np.float32)})
    got = {o.name: tuple(v.shape) for o, v in zip(sess.get_outputs(), outs, strict=True)}
    if got != want:
        raise FetchError(f"{name}: the converted model's outputs {got} differ from the TFLite outputs {want} "
                         "(converter bug: please report it)", EX_SOFTWARE)
    if not all(np.isfinite(v).all() for v in outs):
        raise FetchError(f"{name}: the converted model gives non-finite outputs on a zero input "
                         "(converter bug: please report it)", EX_SOFTWARE)


def fetch_models(models_dir: str | os.PathLike, source: str | os.PathLike | None = None, force: bool = False,
                 say: Callable[[str], None] = lambda _msg: None) -> FetchResult:
    """Make ``models_dir`` hold the verified TFLite models, their ONNX conversions and the manifest.

    Does nothing when the folder is up to date (see ``up_to_date``) unless ``force``. ``source``: a
    mediapipe wheel or a folder (offline install); None = reuse the TFLite files already in the folder when
    they match their pins, else download from PyPI. Raises FetchError (message and sysexits code).
    """
    t0 = time.perf_counter()
    seconds: dict[str, float] = {}
    paths = ModelPaths.in_dir(Path(models_dir).expanduser())
    removed = remove_stale_temporaries(paths.models_dir, say)   # a fetch killed before it renamed its files
    if not force:  # the same pinned inputs give the same files, whatever the source
        manifest = up_to_date(paths)
        if manifest is not None:
            seconds["check"] = time.perf_counter() - t0
            return FetchResult(paths.models_dir, False, manifest, seconds, removed)

    try:
        paths.models_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(paths.models_dir, exc) from exc
    if not os.access(paths.models_dir, os.W_OK | os.X_OK):
        code = errno.EROFS if is_read_only(paths.models_dir) else errno.EACCES
        raise write_error(paths.models_dir, OSError(code, os.strerror(code)))

    t = time.perf_counter()
    got = None if source is not None else _kept_tflite(paths)
    if source is not None:
        data, src = _from_path(Path(source).expanduser())
        origin = str(source)
    elif got is not None:
        (data, src), origin = got, f"{paths.models_dir} (kept from the last fetch)"
        say(f"re-converting the TFLite models kept in {paths.models_dir}")
    else:
        data, src = _download(say)
        origin = src["wheel"]
    _check_pins(data, origin)
    seconds["obtain"] = time.perf_counter() - t

    converted = {}
    for pin in PINNED:
        t = time.perf_counter()
        model = convert(data[pin.name], pin.name.removesuffix(".tflite"), pin.outputs)
        converted[pin.onnx_name] = model.SerializeToString()
        seconds[f"convert {pin.name}"] = time.perf_counter() - t
        t = time.perf_counter()
        _smoke_test(pin.onnx_name, converted[pin.onnx_name], data[pin.name], pin.outputs)
        seconds[f"check {pin.onnx_name}"] = time.perf_counter() - t
        say(f"converted {pin.name} -> {pin.onnx_name} ({len(converted[pin.onnx_name]) / 1e6:.1f} MB)")

    import onnx
    import tflite

    files: dict[str, dict] = {}
    for pin in PINNED:
        files[pin.name] = {"sha256": pin.sha256, "bytes": len(data[pin.name]), "member": pin.member}
        blob = converted[pin.onnx_name]
        files[pin.onnx_name] = {"sha256": _sha256(blob), "bytes": len(blob), "converted_from": pin.name,
                                "opset": OPSET, "outputs": list(pin.outputs) if pin.outputs else "all"}
    manifest = {
        "format": MANIFEST_FORMAT,
        "converter_version": CONVERTER_VERSION,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "source": src,
        "files": files,
        "tools": {"python": sys.version.split()[0], "numpy": np.__version__, "onnx": onnx.__version__,
                  "tflite": getattr(tflite, "__version__", "unknown")},
    }
    t = time.perf_counter()
    blobs = {name: blob for pin in PINNED for name, blob in ((pin.name, data[pin.name]),
                                                             (pin.onnx_name, converted[pin.onnx_name]))}
    _replace_all(paths.models_dir, {**blobs, MANIFEST: (json.dumps(manifest, indent=2) + "\n").encode()})
    seconds["write"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t0
    return FetchResult(paths.models_dir, True, manifest, seconds, removed)
