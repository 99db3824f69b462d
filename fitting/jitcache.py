"""Keep numba's on-disk cache of the fitting kernels consistent with their sources.

numba's ``cache=True`` keys each cached function on its own source file's timestamp only: a kernel in
``udeas.py`` that inlines ``kernels.pose_loss`` keeps its old machine code after ``kernels.py`` changes.
Before the kernels are first compiled or loaded, :func:`ensure_fresh` hashes every kernel source file and,
when the hash differs from the one stored beside the cache, deletes the fitting package's cache files.
Only this package's own ``__pycache__`` entries are touched.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

_HERE = Path(__file__).resolve().parent
KERNEL_MODULES = ("kernels", "udeas", "refine")
_done = False


def _cache_dir() -> Path:
    override = os.environ.get("NUMBA_CACHE_DIR")
    if override:
        # numba mirrors the source path below NUMBA_CACHE_DIR
        return Path(override) / _HERE.relative_to(_HERE.anchor)
    return _HERE / "__pycache__"


def sources_hash() -> str:
    h = hashlib.sha256()
    for name in KERNEL_MODULES:
        h.update((_HERE / f"{name}.py").read_bytes())
    return h.hexdigest()


def ensure_fresh() -> None:
    """Delete stale numba cache files of the kernel modules (once per process; never raises)."""
    global _done
    if _done:
        return
    _done = True
    try:
        cache = _cache_dir()
        stamp = cache / "numba-kernels.sha256"
        digest = sources_hash()
        if stamp.is_file() and stamp.read_text().strip() == digest:
            return
        if cache.is_dir():
            for path in cache.iterdir():
                if path.suffix in (".nbi", ".nbc") and path.name.split(".", 1)[0] in KERNEL_MODULES:
                    path.unlink(missing_ok=True)
        cache.mkdir(parents=True, exist_ok=True)
        stamp.write_text(digest + "\n")
    except OSError:
        pass  # a read-only install: numba falls back to compiling in memory
