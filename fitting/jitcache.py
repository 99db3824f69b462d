"""Keep numba's on-disk cache of the fitting kernels consistent with their sources.

numba's ``cache=True`` keys each cached function on its own source file's timestamp only: a kernel in
``udeas.py`` that inlines ``loss.pose_loss`` (and through it the forward kinematics, the projection and the
penalties, and the ``layout`` constants frozen into all of them) keeps its old machine code after any of
those files changes. :func:`ensure_fresh` hashes every kernel source file (``KERNEL_MODULES``) and, when the
hash differs from the one stored beside the cache, deletes the fitting package's cache files. It does so in
every folder numba may keep them in, found with numba's own cache locators: ``$NUMBA_CACHE_DIR`` (the
systemd unit sets it; numba names the subfolder ``fitting_<sha1 of the package path>``), the package's
``__pycache__`` and the user-wide cache numba falls back to when that is not writable. Only the kernel
modules' ``.nbi``/``.nbc`` files (and those of the retired ``kernels`` module) are touched.

Importing the kernel modules touches no file: the product calls :func:`ensure_fresh` before it first runs a
kernel (``fitting.fitter.Fitter.__init__``; the tests from ``tests/fitting/conftest.py``).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_HERE = Path(__file__).resolve().parent
# Every module whose source is compiled into a cached kernel: the constants, the kernels and their callers.
KERNEL_MODULES = ("layout", "rotations", "forward_kinematics", "projection", "penalties", "loss", "jacobian",
                  "udeas", "refine", "analytic", "depth_term", "depth_rows", "root", "hypotheses",
                  "orientation", "packing", "reported", "result", "measured", "angle_names", "candidates")
RETIRED_MODULES = ("kernels",)  # split into the modules above; its cache files are deleted with theirs
_OURS = KERNEL_MODULES + RETIRED_MODULES
_done = False


def _cache_dirs() -> list[Path]:
    """The folders numba may cache this package's kernels in, in numba's order of preference."""
    from numba.core import caching, config

    source = str(_HERE / f"{KERNEL_MODULES[0]}.py")  # any file of the package: numba keys the folder on it
    locators = [caching.InTreeCacheLocator, caching.UserWideCacheLocator]
    if config.CACHE_DIR:
        locators.insert(0, caching.UserProvidedCacheLocator)
    return [Path(cls(ensure_fresh, source).get_cache_path()) for cls in locators]


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
        digest = sources_hash()
        caches = _cache_dirs()
    except (OSError, AttributeError):  # unreadable sources, or a numba without these locators
        return
    stamped = False
    for cache in caches:
        stamp = cache / "numba-kernels.sha256"
        try:
            if stamp.is_file() and stamp.read_text().strip() == digest:
                stamped = True
                continue
            if cache.is_dir():
                for path in cache.iterdir():
                    if path.suffix in (".nbi", ".nbc") and path.name.split(".", 1)[0] in _OURS:
                        path.unlink(missing_ok=True)
            elif stamped:
                continue  # numba will not get this far down its list: leave no empty folder
            cache.mkdir(parents=True, exist_ok=True)
            stamp.write_text(digest + "\n")
            stamped = True
        except OSError:
            continue  # not writable: numba will not cache there either
