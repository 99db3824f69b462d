"""The download behind ``posed models fetch``: the pinned mediapipe wheel from the package index with pip,
and what pip's failure means (no such wheel on the index, the network failing mid-download, a damaged
download, no space for it), each a FetchError saying so and what to do."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from posed.landmarks.convert.fetch_errors import (
    EX_CANTCREAT,
    EX_DATAERR,
    EX_UNAVAILABLE,
    FetchError,
    offline_hint,
)
from posed.landmarks.model_pins import MEDIAPIPE_VERSION, WHEEL_PLATFORM, WHEEL_SHA256

PIP_TIMEOUT_S = 1800


def pip_download(folder: Path) -> Path:
    """Download the pinned mediapipe wheel into ``folder`` with this Python's pip (the PIP_* settings and
    pip.conf apply: index, proxy, cache); its path, or FetchError."""
    plat, py, impl, abi = WHEEL_PLATFORM
    cmd = [sys.executable, "-m", "pip", "download", f"mediapipe=={MEDIAPIPE_VERSION}", "--no-deps",
           "--only-binary=:all:", "--platform", plat, "--python-version", py, "--implementation", impl,
           "--abi", abi, "--disable-pip-version-check", "--no-input", "-d", str(folder)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=PIP_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:
        raise FetchError(f"pip download of mediapipe=={MEDIAPIPE_VERSION} timed out after "
                         f"{PIP_TIMEOUT_S // 60} min. {offline_hint()}", EX_UNAVAILABLE) from exc
    except OSError as exc:
        raise FetchError(f"cannot run pip ({exc}). {offline_hint()}", EX_UNAVAILABLE) from exc
    wheels = sorted(folder.glob("mediapipe-*.whl"))
    if proc.returncode != 0 or not wheels:
        raise pip_failure(proc.returncode, (proc.stderr or "") + (proc.stdout or ""), folder)
    return wheels[0]


def _index() -> str:
    url = os.environ.get("PIP_INDEX_URL", "")
    return f"the package index {url} (PIP_INDEX_URL)" if url else "PyPI (or the index pip.conf names)"


def _what_pip_said(output: str) -> str:
    """pip's own error lines (``ERROR: ...``, ``error: ...``, ``x ...``, the hash lines), else its last
    lines; notes and hints left out."""
    lines = [line.strip() for line in output.splitlines() if line.strip()]
    said = [line for line in lines if line.startswith(("ERROR:", "error:", "×", "╰─>", "Expected sha256",
                                                        "Got ")) or "[Errno" in line]
    if not said:
        said = [line for line in lines if not line.startswith(("note:", "hint:"))][-3:]
    return " | ".join(said)[:600] or "no output"


def pip_failure(returncode: int, output: str, folder: Path) -> FetchError:
    """What pip's failure means, with pip's own words and the fix."""
    plat, py, _impl, _abi = WHEEL_PLATFORM
    said = f"pip exit {returncode}: {_what_pip_said(output)}"
    low = output.lower()
    if "no space left on device" in low:
        return FetchError(f"no space left for the download of mediapipe=={MEDIAPIPE_VERSION} (about 36 MB) in "
                          f"{folder.parent} ({said}); free some space there or point TMPDIR at a folder with "
                          "room", EX_CANTCREAT)
    if "no matching distribution" in low or "could not find a version" in low:
        return FetchError(f"{_index()} has no mediapipe {MEDIAPIPE_VERSION} wheel for {plat}, CPython {py} "
                          f"({said}). posed asks for that one wheel whatever this machine is; check that "
                          "PIP_INDEX_URL or pip.conf names PyPI or a mirror holding it. " + offline_hint(),
                          EX_UNAVAILABLE)
    if "do not match the hashes" in low or "expected sha256" in low or "is invalid" in low \
            or "bad zip" in low or "badzipfile" in low:
        return FetchError(f"the downloaded mediapipe {MEDIAPIPE_VERSION} wheel is damaged ({said}); run the "
                          "fetch again; if it happens again, something between this machine and the index alters "
                          f"downloads (a proxy or a mirror): download the wheel elsewhere, check its sha256 is "
                          f"{WHEEL_SHA256}, and use --from. " + offline_hint(), EX_DATAERR)
    if "incomplete-download" in low or "not enough bytes" in low \
            or "connection interrupted" in low or "connection broken" in low or "incompleteread" in low:
        return FetchError(f"the network failed during the download of mediapipe=={MEDIAPIPE_VERSION} from "
                          f"{_index()} ({said}); run the fetch again when the network is back. " + offline_hint(),
                          EX_UNAVAILABLE)
    return FetchError(f"could not download mediapipe=={MEDIAPIPE_VERSION} from {_index()} ({said}). Offline? "
                      + offline_hint(), EX_UNAVAILABLE)
