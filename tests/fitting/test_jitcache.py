"""The numba cache guard finds the folder numba really caches the kernels in (asked of numba's own dispatcher,
in a fresh process), empties it when the kernel sources change, and runs only when called: importing the
kernel modules deletes nothing, creating a ``Fitter`` does."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from posed.fitting import jitcache

ROOT = Path(__file__).resolve().parents[2]
PROBE = """
import importlib
import json
from pathlib import Path
from posed.fitting import jitcache
modules = [importlib.import_module(f"posed.fitting.{name}") for name in jitcache.KERNEL_MODULES]
jitcache.ensure_fresh()
paths = {str(Path(f._cache._cache_path)) for m in modules for f in vars(m).values() if hasattr(f, "_cache")}
print(json.dumps(sorted(paths)))
"""
# Plants a stale cache file of every kernel module, imports them all (and the fitter), then starts a Fitter.
IMPORT_THEN_START = """
import importlib
import json
from pathlib import Path
from posed.fitting import jitcache
from posed.fitting import loss
cache = Path(loss.pose_loss._cache._cache_path)
stale = [cache / f"{name}.kernel-1.py311.nbi" for name in jitcache.KERNEL_MODULES + jitcache.RETIRED_MODULES]
for path in stale:
    path.write_bytes(b"old machine code")
(cache / "unrelated.thing-1.py311.nbc").write_bytes(b"not ours")
for name in jitcache.KERNEL_MODULES + ("fitter", "problem"):
    importlib.import_module(f"posed.fitting.{name}")
after_import = sorted(p.name for p in stale if p.is_file())
from posed.fitting.fitter import Fitter
Fitter()
after_start = sorted(p.name for p in stale if p.is_file())
unrelated = (cache / "unrelated.thing-1.py311.nbc").is_file()
print(json.dumps({"cache": str(cache), "planted": len(stale), "after_import": after_import,
                  "after_start": after_start, "unrelated": unrelated}))
"""


def _probe(env: dict, script: str = PROBE):
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=120, check=True)
    return json.loads(out.stdout)


@pytest.mark.parametrize("numba_cache_dir", [True, False])
def test_the_stamp_sits_where_numba_caches_and_stale_kernels_are_deleted(tmp_path, numba_cache_dir):
    env = dict(os.environ)
    env.pop("NUMBA_CACHE_DIR", None)
    if numba_cache_dir:
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")   # as the systemd unit sets it
    [cache] = _probe(env)
    cache = Path(cache)
    if numba_cache_dir:
        assert cache.is_relative_to(tmp_path / "numba")
    stamp = cache / "numba-kernels.sha256"
    assert stamp.is_file()
    if not numba_cache_dir:
        return  # the package's own __pycache__: shared with the other tests, not made stale here
    stale = cache / "loss.pose_loss-1.py311.nbi"
    stale.write_bytes(b"old machine code")
    retired = cache / "kernels.pose_loss-1.py311.nbi"     # the module the kernels were split from
    retired.write_bytes(b"old machine code")
    other = cache / "unrelated.thing-1.py311.nbi"
    other.write_bytes(b"not ours")
    _probe(env)                                            # same sources: nothing deleted
    assert stale.is_file() and retired.is_file()
    stamp.write_text("0" * 64 + "\n")                      # the sources changed since the cache was made
    _probe(env)
    assert not stale.exists() and not retired.exists() and other.is_file()
    assert len(stamp.read_text().strip()) == 64 and stamp.read_text().strip() != "0" * 64


def test_importing_the_kernels_deletes_nothing_until_the_fitter_starts(tmp_path):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")       # fresh: no stamp, so every kernel file is stale
    out = _probe(env, IMPORT_THEN_START)
    assert Path(out["cache"]).is_relative_to(tmp_path / "numba")
    assert out["planted"] == len(jitcache.KERNEL_MODULES) + len(jitcache.RETIRED_MODULES)
    assert len(out["after_import"]) == out["planted"]     # importing touched nothing
    assert out["after_start"] == [] and out["unrelated"]  # Fitter() ran the guard: ours gone, others kept


def _fitting_imports(path: Path) -> set[str]:
    """The fitting modules ``path`` imports (``from posed.fitting import x``, ``from posed.fitting.x import ...``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module == "posed.fitting":
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("posed.fitting."):
            out.add(node.module.split(".")[2])
    return out


def test_every_kernel_source_is_hashed():
    """numba freezes what a kernel calls and reads into its machine code: every module with kernels, and
    every fitting module they import, must be in the hash."""
    fitting_dir = ROOT / "fitting"
    njit_modules = {p.stem for p in fitting_dir.glob("*.py") if "@njit" in p.read_text()}
    assert njit_modules <= set(jitcache.KERNEL_MODULES)
    for name in jitcache.KERNEL_MODULES:
        assert _fitting_imports(fitting_dir / f"{name}.py") <= set(jitcache.KERNEL_MODULES), name
    assert not any((fitting_dir / f"{name}.py").exists() for name in jitcache.RETIRED_MODULES)
