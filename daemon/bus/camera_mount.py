"""The camera's pose as the robot puts it on ``posed/ROBOT/camera/mount`` (docs/falls.md, "The camera's pose
from the robot").

A payload is one JSON object::

    {"format": "posed.camera_mount", "version": 1, "time_unix": 1765100000.25, "height_m": 1.12,
     "down": [0.0, 0.94, 0.34], "valid_s": 0.5, "source": "tf:base_link->camera_color_optical_frame"}

* ``down``: gravity in the camera's axes (x image right, y image down, z forward), any length; or instead
  ``tilt_deg`` and ``roll_deg`` (the convention and signs of ``falls.camera_tilt_deg``/``camera_roll_deg``:
  pitch down positive, clockwise in the image positive). Exactly one of the two forms.
* ``height_m``: the optical centre's height above the floor, metres (optional: without it only gravity).
* ``time_unix``: when the pose was true, Unix seconds on the host's clock (optional: when received).
* ``valid_s``: how long after ``time_unix`` it holds (default ``DEFAULT_VALID_S``).
* ``source``: free text (what produced it); ``format`` may be omitted; unknown fields are ignored.

Anyone on the bus can put anything there, so :func:`parse_camera_mount` takes raw bytes and accepts only a
bounded object of finite numbers in range; anything else raises :class:`BadMount` saying what is wrong and
what is expected (one line, bounded), as :mod:`daemon.bus.acks` does for acknowledgements.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

from posed.daemon.bus.inbound import payload_text, text_field
from posed.daemon.proc.throttle import shown
from posed.falls.features import gravity_from_tilt

FORMAT = "posed.camera_mount"
VERSION = 1
MAX_PAYLOAD_BYTES = 4096
MAX_SOURCE_CHARS = 128
DEFAULT_VALID_S = 1.0
VALID_S_RANGE = (0.05, 3600.0)
HEIGHT_M_RANGE = (0.05, 5.0)
ANGLE_DEG_RANGE = (-90.0, 90.0)
EXPECTED = ('a JSON object {"format": "posed.camera_mount", "version": 1, "time_unix": <unix s>, '
            '"height_m": <0.05..5>, "down": [x, y, z] or "tilt_deg": <-90..90> and "roll_deg": <-90..90>, '
            '"valid_s": <0.05..3600>, "source": "<text>"}')


class BadMount(ValueError):
    """A payload that is not a camera pose; the message says why (bounded, one line)."""


@dataclass(frozen=True)
class CameraMount:
    """One camera pose as received: ``down`` a unit vector in camera axes (x right, y down, z forward);
    ``height_m`` the optical centre above the floor (m) or None; ``time_unix`` when it was true (Unix s) or
    None (when received); ``valid_s`` how long after that it holds; ``source`` free text or None."""

    down: tuple[float, float, float]
    height_m: float | None = None
    time_unix: float | None = None
    valid_s: float = DEFAULT_VALID_S
    source: str | None = None


def parse_camera_mount(payload: bytes | str) -> CameraMount:
    """The camera pose in a payload; raises :class:`BadMount`."""
    text = payload_text(payload, MAX_PAYLOAD_BYTES, BadMount, EXPECTED)
    try:
        obj = json.loads(text)
    except (ValueError, RecursionError):       # RecursionError: nested deeper than Python's limit
        raise BadMount(f"payload is not JSON; expected {EXPECTED}") from None
    if not isinstance(obj, dict):
        raise BadMount(f"payload is a JSON {type(obj).__name__}, not an object; expected {EXPECTED}")
    fmt = obj.get("format", FORMAT)
    if fmt != FORMAT:
        raise BadMount(f"format {shown(str(fmt))!r} is not {FORMAT!r}")
    version = obj.get("version", VERSION)
    if isinstance(version, bool) or not isinstance(version, int):
        raise BadMount(f'"version" must be the integer {VERSION}, got {shown(repr(version))}')
    if version > VERSION:
        raise BadMount(f"version {version} is newer than this posed reads ({VERSION}): upgrade posed, or send "
                       f"version {VERSION}")
    if version < VERSION:
        raise BadMount(f"version {version} is not {VERSION}")
    has_down = "down" in obj
    angles = [k for k in ("tilt_deg", "roll_deg") if k in obj]
    if has_down and angles:
        raise BadMount('give either "down" or "tilt_deg" and "roll_deg", not both')
    if has_down:
        down = _down(obj["down"])
    elif len(angles) == 2:
        tilt = _number(obj, "tilt_deg", ANGLE_DEG_RANGE, "deg")
        roll = _number(obj, "roll_deg", ANGLE_DEG_RANGE, "deg")
        down = tuple(float(v) for v in gravity_from_tilt(tilt, roll))
    elif angles:
        raise BadMount(f'"{angles[0]}" without "{"roll_deg" if angles[0] == "tilt_deg" else "tilt_deg"}": '
                       'give both, or "down"')
    else:
        raise BadMount(f'no gravity: give "down" [x, y, z] or "tilt_deg" and "roll_deg"; expected {EXPECTED}')
    height = _number(obj, "height_m", HEIGHT_M_RANGE, "m") if "height_m" in obj else None
    t = _number(obj, "time_unix", (0.0, math.inf), "s") if "time_unix" in obj else None
    if t is not None and t <= 0.0:
        raise BadMount('"time_unix" must be Unix seconds after 1970 (above 0)')
    valid = _number(obj, "valid_s", VALID_S_RANGE, "s") if "valid_s" in obj else DEFAULT_VALID_S
    return CameraMount(down, height, t, valid, _source(obj["source"]) if "source" in obj else None)


def _number(obj: dict, key: str, bounds: tuple[float, float], unit: str) -> float:
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadMount(f'"{key}" must be a number ({unit}), not {type(value).__name__}')
    value = _float(value)
    lo, hi = bounds
    if not math.isfinite(value):
        raise BadMount(f'"{key}" must be a finite number ({unit})')
    if not lo <= value <= hi:
        raise BadMount(f'"{key}" {value:g} {unit} is out of range {lo:g}..{hi:g}')
    return value


def _float(value: int | float) -> float:
    """A JSON number as a float; an integer too large for one is infinite (then rejected as not finite)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _down(value) -> tuple[float, float, float]:
    """A down vector: three finite numbers, not all 0, as a unit vector."""
    if not isinstance(value, list) or len(value) != 3:
        raise BadMount(f'"down" must be three numbers [x, y, z] (camera axes: x right, y down, z forward), '
                       f"got {shown(json.dumps(value))}")
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise BadMount(f'"down" must hold numbers only, got {shown(json.dumps(value))}')
    v = [_float(x) for x in value]
    if not all(math.isfinite(x) for x in v):
        raise BadMount('"down" must hold finite numbers')
    n = math.sqrt(sum(x * x for x in v))
    if not n > 1e-9:
        raise BadMount('"down" must not be all 0 (it is the direction of gravity)')
    return (v[0] / n, v[1] / n, v[2] / n)


def _source(value) -> str | None:
    """The free-text ``source``: bounded printable text (None when blank; null is not text)."""
    return text_field(value, "source", MAX_SOURCE_CHARS, BadMount)
