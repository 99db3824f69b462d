"""Messages between the landmark, fitting and publisher stages (small frozen dataclasses, pickled into the
mailboxes). ``t_capture`` is the capture timestamp (monotonic clock) of the frame; ``stamps`` collects
``(mark, monotonic time)`` pairs along the way for the per-stage timings the pose topic carries.
``t_origin`` is where latency counts from: the capture timestamp, except for unpaced replays, whose capture
timestamps follow the recording's time line while frames are read as fast as the pipeline takes them (then
it is the time the capture stage read the frame)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fitting.result import FitResult
from landmarks.recording import LandmarkFrame


@dataclass(frozen=True)
class LandmarkMsg:
    """2D landmarks of one frame, for the fitting stage. ``intrinsics``: an object with fx, fy, cx, cy
    (pixels) or None."""

    frame: LandmarkFrame
    t_capture: float
    image_size: tuple[int, int]
    intrinsics: Any = None
    stamps: tuple[tuple[str, float], ...] = ()
    t_origin: float | None = None     # latency is measured from here (None: from t_capture)


@dataclass(frozen=True)
class FitMsg:
    """The fit of one frame with the landmarks it came from, for the publisher."""

    result: FitResult
    landmarks: LandmarkFrame
    t_capture: float
    image_size: tuple[int, int]
    stamps: tuple[tuple[str, float], ...] = ()
    intrinsics: Any = None
    t_origin: float | None = None


def timing_ms(stamps: tuple[tuple[str, float], ...], t_capture: float, t_out: float) -> dict[str, float]:
    """Per-stage work and end-to-end latency in ms: ``<stage>`` for each ``<stage>_in``/``<stage>_out``
    pair, ``total`` = t_out - t_capture (pass the message's origin) and ``waiting`` = total minus the work."""
    marks = dict(stamps)
    out: dict[str, float] = {}
    work = 0.0
    for name, t_in in stamps:
        if name.endswith("_in") and f"{name[:-3]}_out" in marks:
            ms = (marks[f"{name[:-3]}_out"] - t_in) * 1e3
            out[name[:-3]] = round(ms, 2)
            work += ms
    total = (t_out - t_capture) * 1e3
    out["waiting"] = round(max(0.0, total - work), 2)
    out["total"] = round(total, 2)
    return out


def origin(msg) -> float:
    """The time latency counts from for a LandmarkMsg or FitMsg."""
    return msg.t_capture if msg.t_origin is None else msg.t_origin
