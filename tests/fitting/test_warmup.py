"""``Fitter.warmup`` compiles every kernel a frame can reach before the daemon reports READY: after it, fits in
both modes, with and without intrinsics, landmark noise and depth compile nothing more (checked in a fresh
process, on the numba dispatchers' signatures)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CHILD = r"""
import json
import numpy as np
from numba.core.registry import CPUDispatcher
from posed.camera_model import Intrinsics
from posed.fitting import Fitter
from posed.fitting import jitcache
import importlib

mods = [importlib.import_module(f"posed.fitting.{m}") for m in jitcache.KERNEL_MODULES]
def signatures():
    return {f"{m.__name__}.{n}": len(v.signatures) for m in mods for n, v in vars(m).items()
            if isinstance(v, CPUDispatcher)}

f = Fitter()
f.warmup()
before = signatures()
from posed.fitting.warmup import warmup_depth, warmup_landmarks
rng = np.random.default_rng(5)
k = Intrinsics(610.0, 605.0, 330.0, 235.0, 640, 480)
lm = warmup_landmarks(f.dims, noise_px=2.0, seed=9)
depth = warmup_depth(f.dims, 3.4) + rng.normal(0, 0.03, 33)
depth[[3, 14]] = np.nan
f.reset()
for i, (mode, kw) in enumerate([("image", {}), ("video", {}), ("video", {"intrinsics": k}),
                                 ("image", {"intrinsics": k, "depth_m": depth}),
                                 ("video", {"intrinsics": k, "depth_m": depth})]):
    r = f.fit(lm, i, i / 10, (640, 480), mode=mode, **kw)
    assert r.ok, r.error
after = signatures()
print(json.dumps({"before": before, "after": after}))
"""


def test_warmup_leaves_nothing_to_compile():
    out = subprocess.run([sys.executable, "-c", CHILD], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    grew = {k: (got["before"][k], v) for k, v in got["after"].items() if v != got["before"].get(k)}
    assert grew == {}, f"compiled after warm-up: {grew}"
    assert got["before"]["posed.fitting.depth_rows.depth_term_kernel"] >= 1
