"""The numba cache guard finds the folder numba really caches the kernels in (asked of numba's own dispatcher,
in a fresh process) and empties it when the kernel sources change."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PROBE = """
import json
from pathlib import Path
from fitting import kernels
paths = {str(Path(f._cache._cache_path)) for f in vars(kernels).values() if hasattr(f, "_cache")}
print(json.dumps(sorted(paths)))
"""


def _probe(env: dict) -> list[str]:
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
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
    stale = cache / "kernels.pose_loss-1.py311.nbi"
    stale.write_bytes(b"old machine code")
    other = cache / "unrelated.thing-1.py311.nbi"
    other.write_bytes(b"not ours")
    _probe(env)                                            # same sources: nothing deleted
    assert stale.is_file()
    stamp.write_text("0" * 64 + "\n")                      # the sources changed since the cache was made
    _probe(env)
    assert not stale.exists() and other.is_file()
    assert len(stamp.read_text().strip()) == 64 and stamp.read_text().strip() != "0" * 64
