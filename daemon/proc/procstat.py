"""CPU and memory of processes from /proc (Linux), for the status topic and ``posed bench pipeline``.

RSS counts shared pages (libraries, the frame ring) once per process; PSS divides them among the processes
that map them, so the sum of PSS is the honest total memory of the daemon — but a share changes whenever any
other process on the machine maps the same library. USS (private pages only) does not, so memory growth
is not judged on either: private file-backed pages (the numba cache, mapped libraries) turn "shared" when
another process maps the same file. Growth is judged on anonymous memory (heap, stacks, arenas), which
belongs to the process alone.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


@dataclass(frozen=True)
class ProcSample:
    pid: int
    cpu_s: float          # user + system CPU seconds so far
    rss_mb: float
    pss_mb: float         # NaN when smaps_rollup is not readable
    uss_mb: float = float("nan")   # private clean + dirty pages
    anon_mb: float = float("nan")  # anonymous pages (heap, arenas, stacks)


def sample(pid: int) -> ProcSample | None:
    """CPU time and memory of ``pid`` now, or None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            stat = fh.read().decode()
        fields = stat[stat.rindex(")") + 2:].split()
        cpu = (int(fields[11]) + int(fields[12])) / _TICK
        rss = int(fields[21]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):
        return None
    pss = uss = anon = float("nan")
    try:
        with open(f"/proc/{pid}/smaps_rollup") as fh:
            private = 0
            for line in fh:
                if line.startswith("Pss:"):
                    pss = int(line.split()[1]) / 1024
                elif line.startswith(("Private_Clean:", "Private_Dirty:")):
                    private += int(line.split()[1])
                elif line.startswith("Anonymous:"):
                    anon = int(line.split()[1]) / 1024
            uss = private / 1024
    except (OSError, ValueError):
        pass
    return ProcSample(pid, cpu, rss, pss, uss, anon)


class CpuMeter:
    """CPU percent (100 = one core) of a process between successive calls."""

    def __init__(self) -> None:
        self._last: dict[int, tuple[float, float]] = {}

    def percent(self, s: ProcSample, now: float) -> float | None:
        prev = self._last.get(s.pid)
        self._last[s.pid] = (now, s.cpu_s)
        if prev is None or now <= prev[0]:
            return None
        return 100.0 * (s.cpu_s - prev[1]) / (now - prev[0])
