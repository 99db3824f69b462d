"""Body dimensions of the humanoid model: link lengths, segment masses and the calibration file.

Lengths are in metres. Defaults scale with body height H by the anthropometric ratios of Drillis and
Contini (1966) as tabulated by D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed.
(Wiley 2009), Figure 4.1: shoulder (acromion) height 0.818 H, hip (greater trochanter) height 0.530 H,
knee 0.285 H, ankle 0.039 H, eye 0.936 H, chin 0.870 H, upper arm 0.186 H, forearm 0.146 H, hand 0.108 H,
foot length 0.152 H.

The two widths are not Winter's outer breadths (shoulder 0.259 H, hip 0.191 H): MediaPipe's shoulder and
hip landmarks sit near the joint centres, much closer together. They are 0.209 H and 0.115 H, measured on
the BlazePose world landmarks of the project's real test video (tfjs pose_squats, standing frames,
H from the Drillis-Contini leg length 0.491 H); with the outer breadths the fit of that video turned the
body by 50 degrees to shrink the hips. ``posed calibrate`` measures a person's own widths.

Segment masses are Dempster's fractions of body mass with the centre of mass positions along each segment,
also from Winter, Table 4.1 (hand 0.006, forearm 0.016, upper arm 0.028, thigh 0.100, leg 0.0465,
foot 0.0145, head and neck 0.081, trunk 0.497; the twelve add up to 1).

Calibration file (``posed calibrate`` writes it, ``FitConfig.calibration`` names it): a flat
``key: value`` text, one number per line, ``#`` comments; a strict subset of YAML that this module reads with
the standard library only (the fitting package must not import a YAML parser)::

    format: posed.calibration
    version: 1
    body_height_m: 1.62
    trunk_m: 0.47
    ...
"""

from __future__ import annotations

import math
import operator
import os
from dataclasses import dataclass, fields

SHOULDER_WIDTH = 0.209  # shoulder landmark distance / body height (BlazePose world landmarks, see above)
HIP_WIDTH = 0.115       # hip landmark distance / body height
CALIBRATION_FORMAT = "posed.calibration"
CALIBRATION_VERSION = 1


@dataclass(frozen=True)
class BodyDimensions:
    """Link lengths of the humanoid model, metres (paper Figure 2).

    trunk_m: mid-hip (lumbar joint, the model's root) to mid-shoulder; shoulder_half_m / hip_half_m: half
    the distance between the two shoulder / hip landmarks; upper_arm_m, forearm_m: shoulder-elbow,
    elbow-wrist; thigh_m (l_fe), shank_m (l_tb): hip-knee, knee-ankle; ankle_height_m (l_ca): ankle above
    the sole; foot_length_m: heel to toe tip; hand_m: wrist to finger tip.
    """

    body_height_m: float
    trunk_m: float
    shoulder_half_m: float
    hip_half_m: float
    upper_arm_m: float
    forearm_m: float
    hand_m: float
    thigh_m: float
    shank_m: float
    ankle_height_m: float
    foot_length_m: float

    @classmethod
    def from_height(cls, height_m: float) -> BodyDimensions:
        """Drillis & Contini ratios (Winter 2009, Fig. 4.1) for a body of height ``height_m``."""
        h = float(height_m)
        if not (0.5 <= h <= 2.6) or not math.isfinite(h):
            raise ValueError(f"body height {height_m!r} m is not a human height (0.5..2.6 m)")
        return cls(
            body_height_m=h,
            trunk_m=(0.818 - 0.530) * h,
            shoulder_half_m=SHOULDER_WIDTH * h / 2,
            hip_half_m=HIP_WIDTH * h / 2,
            upper_arm_m=0.186 * h,
            forearm_m=0.146 * h,
            hand_m=0.108 * h,
            thigh_m=(0.530 - 0.285) * h,
            shank_m=(0.285 - 0.039) * h,
            ankle_height_m=0.039 * h,
            foot_length_m=0.152 * h,
        )

    @property
    def leg_m(self) -> float:
        """l_leg = l_fe + l_tb + l_ca (paper, after eq. 8): hip to sole."""
        return self.thigh_m + self.shank_m + self.ankle_height_m

    def as_array(self):
        """The lengths in field order, for the numba kernels (see ``fitting.layout.DM_*``)."""
        import numpy as np

        return np.array(_LENGTHS_OF(self), dtype=np.float64)


# the fields of a BodyDimensions in order, as a tuple (video mode learns a new body on most frames:
# dataclasses.fields on each cost more than the array it fills)
_LENGTHS_OF = operator.attrgetter(*(f.name for f in fields(BodyDimensions)))


# Dempster's segment mass fractions and centre-of-mass positions (fraction of the segment length from its
# proximal end), Winter (2009) Table 4.1. Keys name the model's segments.
SEGMENT_MASS = {
    "trunk": (0.497, 0.50),       # greater trochanter -> glenohumeral joint: mid-hip -> mid-shoulder here
    "head": (0.081, 1.00),        # C7-T1 -> ear canal: the centre of mass sits at the ears
    "upper_arm": (0.028, 0.436),
    "forearm": (0.016, 0.430),
    "hand": (0.006, 0.506),       # wrist axis -> knuckle II of the middle finger
    "thigh": (0.100, 0.433),
    "shank": (0.0465, 0.433),
    "foot": (0.0145, 0.50),       # lateral malleolus -> head of metatarsal II
}


# --- calibration file ----------------------------------------------------------------------------------


class CalibrationError(ValueError):
    """A calibration file that cannot be used; the message names the file, line and fix."""


def write_calibration(path: str | os.PathLike, dims: BodyDimensions, frames: int, source: str = "") -> None:
    """Write ``dims`` in the flat calibration format (also valid YAML)."""
    lines = [
        "# posed calibration: link lengths of one person, metres (written by `posed calibrate`).",
        "# Flat 'key: value' lines only; read by fitting.body.read_calibration.",
        f"format: {CALIBRATION_FORMAT}",
        f"version: {CALIBRATION_VERSION}",
        f"frames: {int(frames)}",
    ]
    if source:
        lines.append(f"source: {_quote(source)}")
    for f in fields(BodyDimensions):
        lines.append(f"{f.name}: {getattr(dims, f.name):.4f}")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(lines) + "\n")


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


MAX_CALIBRATION_BYTES = 65536  # a calibration file is about 1 kB


def read_calibration(path: str | os.PathLike) -> BodyDimensions:
    """Read a calibration file; raises CalibrationError naming what is wrong and how to fix it."""
    try:
        with open(path, "rb") as fh:        # bounded: a huge file or /dev/zero is an error, not a hang
            data = fh.read(MAX_CALIBRATION_BYTES + 1)
    except OSError as exc:
        raise CalibrationError(f"{path}: cannot read the calibration file ({exc.strerror}); "
                               "create it with `posed calibrate RECORDING.landmarks.jsonl -o FILE`") from exc
    if len(data) > MAX_CALIBRATION_BYTES:
        raise CalibrationError(f"{path} is larger than {MAX_CALIBRATION_BYTES} bytes: not a calibration file (one "
                               "is about 1 kB); create it with `posed calibrate RECORDING.landmarks.jsonl -o FILE`")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CalibrationError(f"{path}: not UTF-8 text (byte {data[exc.start]:#04x} at offset {exc.start}); "
                               "create it with `posed calibrate RECORDING.landmarks.jsonl -o FILE`") from None
    values: dict[str, str] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        key, sep, value = line.partition(":")
        key, value = key.strip(), value.strip()
        if not sep or not key or " " in key or raw[:1].isspace():
            raise CalibrationError(f"{path}:{lineno}: expected 'key: value', got {line!r} "
                                   "(the calibration format is flat key: value lines; rewrite it with "
                                   "`posed calibrate`)")
        if value.startswith('"'):
            value = value[1:value.rfind('"')] if value.count('"') >= 2 else value[1:]
        else:
            value = value.split(" #", 1)[0].strip()
        values[key] = value
    if values.get("format") != CALIBRATION_FORMAT:
        raise CalibrationError(f"{path}: format is {values.get('format')!r}, expected {CALIBRATION_FORMAT!r}; "
                               "create the file with `posed calibrate`")
    if values.get("version") != str(CALIBRATION_VERSION):
        raise CalibrationError(f"{path}: version {values.get('version')!r} is not supported "
                               f"(this reader knows {CALIBRATION_VERSION})")
    kwargs = {}
    for f in fields(BodyDimensions):
        if f.name not in values:
            raise CalibrationError(f"{path}: {f.name} is missing; run `posed calibrate` again")
        try:
            v = float(values[f.name])
        except ValueError:
            raise CalibrationError(f"{path}: {f.name} must be a number of metres, got {values[f.name]!r}") from None
        if not math.isfinite(v) or v <= 0 or v > 3.0:
            raise CalibrationError(f"{path}: {f.name} = {v} m is not a plausible length (0..3 m)")
        kwargs[f.name] = v
    return BodyDimensions(**kwargs)


def dimensions_for(height_m: float, calibration: str = "") -> BodyDimensions:
    """The dimensions the fit uses: the calibration file when given, else the height ratios."""
    if calibration:
        return read_calibration(calibration)
    return BodyDimensions.from_height(height_m)
