"""The machine a benchmark ran on, as every ``posed bench NAME --json`` reports it: the CPU's model name, cores,
Python, numpy, the platform and the 1-minute load average (a 2-core machine shared with other jobs: a number
taken under load is said to be)."""

from __future__ import annotations

import os
import platform
import sys

import numpy as np


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (``AMD EPYC ...``), else what the platform says, else ""."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or ""


def machine() -> dict:
    """``{"cpu", "cores", "python", "numpy", "platform", "load_avg_1m"}`` of this machine, now."""
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "python": sys.version.split()[0], "numpy": np.__version__,
            "platform": platform.platform(), "load_avg_1m": round(load, 2)}
