"""The errors of ``posed models fetch``: each says what is wrong and how to fix it, with a sysexits code."""

from __future__ import annotations

import errno
import os
from pathlib import Path

from posed.landmarks.model_pins import DETECTOR_TFLITE, LANDMARK_TFLITE, MEDIAPIPE_VERSION, WHEEL_PLATFORM

EX_DATAERR, EX_UNAVAILABLE, EX_SOFTWARE, EX_CANTCREAT, EX_IOERR = 65, 69, 70, 73, 74


class FetchError(RuntimeError):
    """``posed models fetch`` failed; the message says what and how to fix it; ``exit_code`` is a
    sysexits code."""

    def __init__(self, message: str, exit_code: int = EX_SOFTWARE) -> None:
        super().__init__(message)
        self.exit_code = exit_code


def offline_hint() -> str:
    plat, py, impl, abi = WHEEL_PLATFORM
    return (f"On a machine with internet access, run `pip download mediapipe=={MEDIAPIPE_VERSION} --no-deps "
            f"--only-binary=:all: --platform {plat} --python-version {py} --implementation {impl} "
            f"--abi {abi} "
            f"-d DIR`, copy DIR here and run `posed models fetch --from DIR` (a folder holding "
            f"{DETECTOR_TFLITE} and {LANDMARK_TFLITE} works too)")


def is_read_only(path: Path) -> bool:
    """Whether the file system holding ``path`` (or its nearest existing parent) is mounted read-only."""
    for p in (path, *path.parents):
        try:
            return bool(os.statvfs(p).f_flag & os.ST_RDONLY)
        except OSError:
            continue
    return False


def write_error(path: Path, exc: OSError) -> FetchError:
    """What a failed write of ``path`` means and what to do (73 for space and permissions, 74 otherwise)."""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return FetchError(f"no space left writing {path} (a fetch needs about 34 MB free beside the models it "
                          "replaces, which stay as they were until the new ones are complete); free some space "
                          "or choose another folder with --models-dir or POSED_MODELS_DIR", EX_CANTCREAT)
    if exc.errno == errno.EROFS or (exc.errno in (errno.EACCES, errno.EPERM) and is_read_only(path)):
        return FetchError(f"cannot write {path}: the file system is read-only; remount it read-write or choose "
                          "a writable folder with --models-dir or POSED_MODELS_DIR", EX_CANTCREAT)
    if exc.errno in (errno.EACCES, errno.EPERM):
        return FetchError(f"cannot write {path}: {exc.strerror}; choose a writable folder with --models-dir "
                          "or POSED_MODELS_DIR (or fix the folder's permissions)", EX_CANTCREAT)
    return FetchError(f"cannot write {path}: {exc}", EX_IOERR)
