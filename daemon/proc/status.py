"""Numbers of the status object (posed/ROBOT/status): per-process CPU and memory from /proc, rounded for
JSON (NaN and missing values become null)."""

from __future__ import annotations

import math

from posed.daemon.proc import procstat


def rounded(v, nd: int = 1):
    """``v`` rounded to ``nd`` decimals, or None when it is missing or NaN."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return round(float(v), nd)


def fmt_ms(v) -> str:
    """A millisecond value for STATUS= text: whole milliseconds, or "-" when unknown."""
    return "-" if v is None else f"{v:.0f}"


def nan_to_zero(v: float) -> float:
    return 0.0 if math.isnan(v) else v


def pss_mb(s: procstat.ProcSample) -> float:
    """Proportional set size in MB, or RSS where the kernel gives no PSS."""
    return s.rss_mb if math.isnan(s.pss_mb) else s.pss_mb


def memory_fields(s: procstat.ProcSample, cpu_pct: float) -> dict:
    """One process's CPU and memory entry of the status object."""
    return {"cpu_pct": rounded(cpu_pct), "rss_mb": round(s.rss_mb, 1), "pss_mb": rounded(s.pss_mb),
            "uss_mb": rounded(s.uss_mb), "anon_mb": rounded(s.anon_mb)}
