"""The daemon's one clock: ``time.monotonic()`` (CLOCK_MONOTONIC, shared by every process on the machine).

Capture timestamps are taken on it by the capture stage and travel with each frame to the publisher, so
latency (publish time minus capture time) and fall timing never mix clocks. Wall time appears only in what
is shown to people (``wall_from_monotonic``).
"""

from __future__ import annotations

import time
from datetime import UTC, datetime


def now() -> float:
    """Seconds on the monotonic clock."""
    return time.monotonic()


def wall_from_monotonic(t: float) -> float:
    """Unix seconds of a monotonic timestamp ``t`` (taken in any process of this boot)."""
    return time.time() - (time.monotonic() - t)


def iso(unix: float) -> str:
    """ISO 8601 UTC with milliseconds."""
    return datetime.fromtimestamp(unix, UTC).isoformat(timespec="milliseconds")


def monotonic_from_wall(unix: float) -> float:
    """Monotonic seconds of a Unix time ``unix`` taken on this machine's clock (the inverse of
    :func:`wall_from_monotonic`)."""
    return unix - (time.time() - time.monotonic())
