"""What the topics carry (interfaces.md section 4): JSON text without NaN, the pose and landmarks objects."""

from __future__ import annotations

import json
import math

from daemon import clock
from daemon.messages import FitMsg, origin, timing_ms


def dumps(obj) -> str:
    """JSON without NaN/Infinity (not JSON): such numbers become null."""
    try:
        return json.dumps(obj, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(obj), allow_nan=False)


def _finite(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def pose_message(msg: FitMsg, now: float) -> dict:
    """The pose topic's JSON object for one FitMsg: the fit result (interfaces.md section 2) plus
    ``time_unix`` (the capture time in unix seconds), ``image_size`` and ``timing_ms`` (per-stage work and
    latency up to ``now``, seconds on the monotonic clock)."""
    out = msg.result.to_json()
    out.setdefault("time_unix", round(clock.wall_from_monotonic(msg.t_capture), 4))
    out.setdefault("image_size", list(msg.image_size))
    out.setdefault("timing_ms", timing_ms(msg.stamps, origin(msg), now))
    return out


def landmarks_message(msg: FitMsg) -> dict:
    """The landmarks topic's JSON object: the frame object of interfaces.md section 1 plus ``image_size``."""
    out = msg.landmarks.to_json()
    out["image_size"] = list(msg.image_size)
    return out
