"""daemon.proc.orphans finds hook processes by the owner tag in their environment, real processes."""

import os
import subprocess
import sys

from posed.daemon.proc import orphans


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_processes_are_found_by_owner_and_ended():
    dead = _dead_pid()
    sleep = [sys.executable, "-c", "import time; time.sleep(60)"]
    mine = subprocess.Popen(sleep, env={**os.environ, orphans.OWNER_ENV: orphans.owner_tag(os.getpid(), 4242)})
    stale = subprocess.Popen(sleep, env={**os.environ, orphans.OWNER_ENV: orphans.owner_tag(dead, 17)})
    plain = subprocess.Popen(sleep)
    try:
        assert orphans.of_stage(os.getpid(), 4242) == [mine.pid]
        assert orphans.of_stage(os.getpid(), 4243) == []
        assert orphans.of_supervisor(os.getpid()) == [mine.pid]
        found = orphans.of_dead_supervisors()
        assert stale.pid in found and mine.pid not in found and plain.pid not in found
        assert orphans.end([mine.pid, stale.pid], grace_s=2.0) == 2
        assert mine.wait(5) is not None and stale.wait(5) is not None
        assert plain.poll() is None
    finally:
        for p in (mine, stale, plain):
            p.kill()
            p.wait()
