"""``posed warmup``: compile the fitting kernels (numba) into the on-disk cache ahead of the first start.

numba compiles the fit's kernels the first time a process runs them (about 25 s on a 2-core x86-64) and keeps
the machine code in its cache: ``$NUMBA_CACHE_DIR`` when set (the systemd unit sets
/var/cache/posed/numba; deploy/install.sh warms it as the service's user), else the fitting package's
``__pycache__``, else numba's user-wide cache when that is not writable. Later processes load it in well
under a second. deploy/install.sh and the Makefile run this step; ``posed run`` and ``posed fit`` would
otherwise compile on their first start (saying so), before the daemon reports READY.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable

from posed.commands import add_config_args, config_from_args

SAY_AFTER_S = 5.0   # a warm cache loads in 1-4 s even on a busy 2-core machine: say nothing then


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("warmup", help="compile the fitting kernels (numba) into the cache, so that the "
                                           "first start is quick",
                            description=(__doc__ or "").split("\n\n")[1].replace("\n", " "))
    add_config_args(parser, source=False, example="fitting.restarts=10")
    parser.add_argument("--no-check", action="store_true",
                        help="do not time a new process loading the kernels from the cache afterwards")
    parser.set_defaults(func=run)


def cache_location() -> str:
    """Where numba keeps the kernels for this process, in words."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    return "the fitting package's __pycache__ (or numba's user-wide cache if that is not writable)"


def warm_fitter(fitter, say: Callable[[str], None], after_s: float = SAY_AFTER_S) -> float:
    """``fitter.warmup()``, saying what is going on when it takes longer than ``after_s`` (a cold cache:
    compiling); returns the seconds it took."""
    done = threading.Event()

    def announce() -> None:
        if not done.wait(after_s):
            say(f"compiling the fitting kernels (numba) into {cache_location()}: once after an install or "
                "update, about 30 s on an idle 2-core machine; `posed warmup` does it ahead")

    t0 = time.perf_counter()
    watcher = threading.Thread(target=announce, name="warmup-notice", daemon=True)
    watcher.start()
    try:
        fitter.warmup()
    finally:
        done.set()
        watcher.join()
    return time.perf_counter() - t0


def run(args: argparse.Namespace) -> int:
    from posed.fitting import CalibrationError, Fitter

    def say(msg: str) -> None:
        print(f"posed warmup: {msg}", flush=True)

    cfg = config_from_args(args).fitting
    try:
        fitter = Fitter(cfg)
    except CalibrationError as exc:
        print(f"posed warmup: {exc} (fitting.calibration in the config)", file=sys.stderr)
        return 2
    say(f"loading or compiling the fitting kernels; numba cache: {cache_location()}")
    seconds = warm_fitter(fitter, say)
    say(f"kernels ready in {seconds:.1f} s")
    if args.no_check:
        return 0
    # what the service's first start will see: a new process loading them from the cache
    # -P: not the current folder first on sys.path (run from a checkout, it would load that copy of the
    # package, whose kernels numba caches apart from the installed one's)
    check = subprocess.run([sys.executable, "-P", "-c", CHECK], capture_output=True, text=True, timeout=600)
    if check.returncode != 0:
        print(f"posed warmup: a new process could not load the kernels: {check.stderr.strip()[-500:]}",
              file=sys.stderr)
        return 1
    load_s = float(check.stdout.split()[-1])
    say(f"a new process loads them in {load_s:.1f} s" + (
        "" if load_s < COLD_S else f" (more than {COLD_S:g} s: the cache at {cache_location()} is not used; "
                                   "is it writable by this user?)"))
    return 0 if load_s < COLD_S else 1


# Runs in a fresh interpreter: the time to load (not compile) every kernel, on the last line of stdout.
CHECK = """
import time
t0 = time.perf_counter()
from posed.fitting import FitConfig, Fitter
Fitter(FitConfig()).warmup()
print(round(time.perf_counter() - t0, 3))
"""
COLD_S = 10.0   # loading takes ~1-2 s; compiling ~25 s: between the two, this tells them apart
