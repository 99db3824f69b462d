"""2D landmarks per frame and the ``*.landmarks.jsonl`` recording format (interfaces.md section 1).

A recording is JSON Lines: a header line, then one frame per line. Landmarks are 33 rows of
``[x, y, z, visibility, presence]`` in MediaPipe Pose order; x, y are image pixels (x right, y down), z is
MediaPipe's relative depth on the x scale (negative nearer the camera, 0 when unknown). In memory a frame's
landmarks are a (33, 5) float64 array; a landmark that is ``null`` in the file is a row of NaN, and so is one
with a NaN or infinite value (JSON has no such numbers, but some writers emit them): unknown, the frame kept.
So is one whose visibility or presence is outside [0, 1] (interfaces.md: "visibility, presence: 0..1"; a
probability of 1.7 or -0.2 says its extractor is broken, and its x and y cannot be trusted either). Those are
not silent: the stream counts them (:class:`InvalidValues`, ``stream.invalid``) and, when it ends, reports how
many values on how many lines and the first of them with an :class:`InvalidLandmarkValues` warning (shown on
stderr by default: the commands and the daemon's capture stage say it).

Depth (optional): a frame may carry ``depth_m``, 33 depths in metres along the camera's z axis that a depth
camera aligned to the image measured at the landmarks' pixels (``null`` where unknown; in memory a (33,)
float64 array with NaN, see :mod:`landmarks.depth`), and the header then says where it came from,
``"depth": {"source": "realsense", "aligned_to": "color"}`` (:class:`DepthSource`). A recording without them
reads and writes exactly as before.

People (optional): with several people in view a frame also carries ``people``, one :class:`PersonLandmarks`
per person (``{"id": track id, "landmarks": [...], "world": [...], "depth_m": [...]}``); the frame's own
``landmarks``/``world``/``depth_m`` stay those of one person (the one followed longest), so a reader that knows
one person keeps working. A frame without ``people`` reads and writes exactly as before.

Reading never raises on a bad frame line: it yields a :class:`RecordingProblem` naming the file and line and
goes on. Only a header that cannot be understood raises :class:`RecordingError` (nothing after it can be read).
No line is read whole beyond ``MAX_LINE_BYTES`` (a frame line is a few kB): a longer header is a
RecordingError, a longer frame line is a RecordingProblem that ends the stream (a 2 GB line or ``/dev/zero``
is reported in bounded memory, not read).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, TextIO

import numpy as np

from posed.camera_model import Intrinsics

FORMAT = "posed.landmarks"
VERSION = 1
NUM_LANDMARKS = 33
MAX_LINE_BYTES = 1 << 20        # 1 MiB; a frame line with depth is about 3 kB

LANDMARK_NAMES = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye", "right_eye_outer",
    "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder", "right_shoulder", "left_elbow",
    "right_elbow", "left_wrist", "right_wrist", "left_pinky", "right_pinky", "left_index", "right_index",
    "left_thumb", "right_thumb", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle",
    "right_ankle", "left_heel", "right_heel", "left_foot_index", "right_foot_index",
)


class RecordingError(ValueError):
    """A recording that cannot be read at all (missing file, bad header)."""


@dataclass(frozen=True)
class DepthSource:
    """Where a recording's ``depth_m`` came from: the header's ``"depth"`` object.

    ``source``: the depth camera (``"realsense"``); ``aligned_to``: the image its depth was aligned to
    (``"color"``: the image the landmarks are in). ``extra`` keeps fields this version does not know.
    """

    source: str = "realsense"
    aligned_to: str = "color"
    extra: dict = field(default_factory=dict, compare=False)

    def to_json(self) -> dict:
        out: dict[str, Any] = {"source": self.source, "aligned_to": self.aligned_to}
        for k, v in self.extra.items():
            out.setdefault(k, v)
        return out

    @classmethod
    def from_json(cls, obj: Any) -> DepthSource:
        """Parse the header's ``depth`` object; raises ValueError naming the wrong field."""
        if not isinstance(obj, dict):
            raise ValueError(f'depth must be an object like {{"source": "realsense", "aligned_to": "color"}}, '
                             f"got {obj!r}")
        for key in ("source", "aligned_to"):
            if not isinstance(obj.get(key), str):
                raise ValueError(f"depth.{key} must be a string, got {obj.get(key)!r}")
        extra = {k: v for k, v in obj.items() if k not in ("source", "aligned_to")}
        return cls(obj["source"], obj["aligned_to"], extra)


@dataclass(frozen=True)
class RecordingHeader:
    """First line of a recording. ``extra`` keeps fields this version does not know, for round trips.

    ``camera``: the intrinsics of the recorded image (their width and height are ``image_size``; the file's
    ``camera`` object holds only fx, fy, cx, cy), or None. ``depth``: where the frames' ``depth_m`` came
    from, or None (a recording without depth).
    """

    image_size: tuple[int, int]
    fps: float
    source: str = ""
    camera: Intrinsics | None = None
    extra: dict = field(default_factory=dict, compare=False)
    depth: DepthSource | None = None

    def __post_init__(self) -> None:
        if self.camera is not None and self.camera.size != tuple(self.image_size):
            raise ValueError(f"camera intrinsics are of a {self.camera.width}x{self.camera.height} image, the "
                             f"recording's image_size is {self.image_size[0]}x{self.image_size[1]}")

    def to_json(self) -> dict:
        out: dict[str, Any] = {"format": FORMAT, "version": VERSION, "image_size": list(self.image_size),
                               "fps": self.fps, "source": self.source}
        if self.camera is not None:
            out["camera"] = self.camera.to_json(with_size=False)
        if self.depth is not None:
            out["depth"] = self.depth.to_json()
        for k, v in self.extra.items():
            out.setdefault(k, v)
        return out

    @classmethod
    def from_json(cls, obj: Any) -> RecordingHeader:
        """Parse a header object; raises ValueError naming the first wrong field."""
        if not isinstance(obj, dict):
            raise ValueError("the header must be a JSON object")
        if obj.get("format") != FORMAT:
            raise ValueError(f"format is {obj.get('format')!r}, expected {FORMAT!r}")
        if obj.get("version") != VERSION:
            raise ValueError(f"version {obj.get('version')!r} is not supported (this reader knows {VERSION})")
        size = obj.get("image_size")
        if (not isinstance(size, list) or len(size) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)):
            raise ValueError(f"image_size must be [W, H] positive integers, got {size!r}")
        fps = obj.get("fps")
        if not _is_number(fps) or fps <= 0:
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        source = obj.get("source", "")
        if not isinstance(source, str):
            raise ValueError(f"source must be a string, got {source!r}")
        camera = None
        if obj.get("camera") is not None:
            cam = obj["camera"]
            if not isinstance(cam, dict) or not all(_is_number(cam.get(k)) for k in ("fx", "fy", "cx", "cy")):
                raise ValueError(f"camera must be {{fx, fy, cx, cy}} numbers, got {cam!r}")
            try:
                camera = Intrinsics.from_json(cam, image_size=(size[0], size[1]))
            except ValueError as exc:
                raise ValueError(f"camera: {exc}") from None
        depth = None
        if obj.get("depth") is not None:
            depth = DepthSource.from_json(obj["depth"])
        known = {"format", "version", "image_size", "fps", "source", "camera"} | ({"depth"} if depth else set())
        extra = {k: v for k, v in obj.items() if k not in known}
        return cls((size[0], size[1]), float(fps), source, camera, extra, depth)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _non_finite(entry: Any) -> bool:
    """Five numbers, one of them NaN or infinite: a landmark its extractor did not know."""
    return (isinstance(entry, list) and len(entry) == 5
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in entry)
            and not all(math.isfinite(v) for v in entry))


PROBABILITIES = ((3, "visibility"), (4, "presence"))


def _out_of_range(entry: list) -> list[tuple[str, float]]:
    """Of five finite numbers ``[x, y, z, visibility, presence]``: the probabilities outside [0, 1]."""
    return [(name, entry[i]) for i, name in PROBABILITIES if not 0.0 <= entry[i] <= 1.0]


class InvalidLandmarkValues(UserWarning):
    """A recording held landmarks whose visibility or presence is outside [0, 1] (read as unknown)."""


@dataclass
class InvalidValues:
    """The visibility and presence values outside [0, 1] a recording's stream met (each made its landmark
    unknown): how many values, on how many landmarks and frame lines, and the first of them."""

    path: str = ""
    values: int = 0
    landmarks: int = 0
    lines: int = 0
    first: str = ""        # e.g. "line 5: landmark 25 (left_knee) visibility 1.7"

    def add(self, line: int, found: list[tuple[str, str, float]]) -> None:
        """The out-of-range values of one frame line: (landmark, field, value) each."""
        if not found:
            return
        if not self.lines:
            where, name, value = found[0]
            self.first = f"line {line}: {where} {name} {value!r}"
        self.lines += 1
        self.values += len(found)
        self.landmarks += len({where for where, _, _ in found})

    def __bool__(self) -> bool:
        return self.values > 0

    def __str__(self) -> str:
        return (f"{self.path}: {self.values} visibility or presence value(s) outside [0, 1] on {self.lines} "
                f"line(s) (first: {self.first}); each such landmark ({self.landmarks} in all) was read as "
                "unknown, as null is, and its frame kept (the spec says 0..1: the recording's extractor wrote "
                "something that is not a probability)")


@dataclass(frozen=True, eq=False)
class PersonLandmarks:
    """One person of a frame's ``people``: ``id`` the track id (stable while the person stays in view,
    :mod:`landmarks.tracks`), ``landmarks`` (33, 5) as :attr:`LandmarkFrame.landmarks` (never None), ``world``
    and ``depth_m`` as there (None when unknown)."""

    id: int
    landmarks: np.ndarray
    world: np.ndarray | None = None
    depth_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.id, (int, np.integer)) or isinstance(self.id, bool) or self.id < 0:
            raise ValueError(f"a person's id must be a non-negative integer (a track id), got {self.id!r}")
        object.__setattr__(self, "id", int(self.id))
        if self.landmarks is None:
            raise ValueError("a person of 'people' must have landmarks (33 entries)")
        # the same checks as a frame's (shape, NaN rows, positive depths)
        check = LandmarkFrame(0, 0.0, self.landmarks, depth_m=self.depth_m, world=self.world)
        object.__setattr__(self, "landmarks", check.landmarks)
        object.__setattr__(self, "world", check.world)
        object.__setattr__(self, "depth_m", check.depth_m)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PersonLandmarks):
            return NotImplemented
        return self.id == other.id and LandmarkFrame(0, 0.0, self.landmarks, depth_m=self.depth_m,
                                                     world=self.world) == LandmarkFrame(
            0, 0.0, other.landmarks, depth_m=other.depth_m, world=other.world)

    __hash__ = None  # type: ignore[assignment]

    def to_json(self) -> dict:
        out: dict[str, Any] = {"id": self.id, "landmarks": _rows_json(self.landmarks)}
        if self.world is not None:
            out["world"] = _rows_json(self.world)
        if self.depth_m is not None:
            out["depth_m"] = [None if np.isnan(v) else float(v) for v in self.depth_m]
        return out

    @classmethod
    def from_json(cls, obj: Any, index: int = 0, invalid: list | None = None) -> PersonLandmarks:
        """Parse one entry of ``people``; raises ValueError naming ``people[index]`` and what is wrong.
        Visibility or presence outside [0, 1] make their landmark unknown, each listed in ``invalid``."""
        where = f"people[{index}]"
        if not isinstance(obj, dict):
            raise ValueError(f'{where} must be an object {{"id": N, "landmarks": [...]}}, got {obj!r:.60}')
        pid = obj.get("id")
        if not isinstance(pid, int) or isinstance(pid, bool) or pid < 0:
            raise ValueError(f"{where}.id must be a non-negative integer (a track id), got {pid!r}")
        try:
            found: list = []
            lms = _parse_rows(obj.get("landmarks"), "landmarks", "[x, y, z, visibility, presence]", found)
            if lms is None:
                raise ValueError("landmarks are missing (33 entries)")
            world = _parse_rows(obj.get("world"), "world", "[x, y, z, visibility, presence] (metres)", found)
            depth = _parse_depth_m(obj.get("depth_m"))
            person = cls(pid, lms, world, depth)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        if invalid is not None:
            invalid += [(f"{where} {w}", name, v) for w, name, v in found]
        return person


def _parse_people(raw: Any, invalid: list | None = None) -> tuple[PersonLandmarks, ...]:
    if not isinstance(raw, list):
        raise ValueError(f"people must be a list of persons, got {type(raw).__name__}")
    people = tuple(PersonLandmarks.from_json(p, i, invalid) for i, p in enumerate(raw))
    ids = [p.id for p in people]
    if len(set(ids)) != len(ids):
        raise ValueError(f"people: every person needs their own id, got ids {ids}")
    return people


@dataclass(frozen=True, eq=False)
class LandmarkFrame:
    """The 2D landmarks of one frame.

    seq: frame sequence number; t: capture time in seconds from the start of the recording (or of the
    daemon's monotonic clock); landmarks: (33, 5) float64 ``[x_px, y_px, z, visibility, presence]`` with NaN
    rows for unknown landmarks, or None when there is no person. ``extra`` keeps unknown JSON fields.
    depth_m: (33,) float64, the depth in metres along the camera's z axis that a depth camera aligned to the
    image measured at each landmark's pixel (:func:`landmarks.sample_depth`), NaN where unknown; None when
    the frame has no depth (no depth camera, or no person).
    gravity: the direction of gravity (down) in the camera's axes (x right, y down, z forward; any length), from
    the camera's accelerometer (a RealSense D435i/D455, ``hal.imu``), or None. A recording line's ``"gravity"``
    that is not three finite numbers stays in ``extra`` (so the line and its landmarks are kept).
    world: (33, 5) float64 ``[x, y, z, visibility, presence]``, BlazePose's own 3D world landmarks of the frame:
    metres, origin at the middle of the hips, MediaPipe's world axes (x to the image's right, y down, z away
    from the camera, roughly aligned with it), NaN rows where unknown; None when the extractor gave none (or
    no person). The daemon's landmark stage writes them smoothed, as MediaPipe's own tracker does.
    people: every person of the frame (:class:`PersonLandmarks`, track ids) when the extractor followed several,
    else None (then the frame is written exactly as a one-person frame). ``landmarks`` stays one person's.
    """

    seq: int
    t: float
    landmarks: np.ndarray | None
    extra: dict = field(default_factory=dict)
    depth_m: np.ndarray | None = None
    gravity: tuple[float, float, float] | None = None
    world: np.ndarray | None = None
    people: tuple[PersonLandmarks, ...] | None = None

    def __post_init__(self) -> None:
        if self.people is not None:
            people = tuple(self.people)
            if not all(isinstance(p, PersonLandmarks) for p in people):
                raise ValueError("people must be PersonLandmarks (id, landmarks, world, depth_m)")
            object.__setattr__(self, "people", people)
        if self.landmarks is not None:
            arr = np.asarray(self.landmarks, dtype=np.float64)
            if arr.shape != (NUM_LANDMARKS, 5):
                raise ValueError(f"landmarks must have shape (33, 5), got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, "landmarks", arr)
        if self.depth_m is not None:
            depth = np.array(self.depth_m, dtype=np.float64)
            if depth.shape != (NUM_LANDMARKS,):
                raise ValueError(f"depth_m must have shape (33,) (metres, NaN unknown), got {depth.shape}")
            bad = ~(np.isnan(depth) | (np.isfinite(depth) & (depth > 0)))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(f"depth_m must hold positive finite metres or NaN (unknown); depth_m[{i}] "
                                 f"({LANDMARK_NAMES[i]}) is {float(depth[i])!r}")
            depth.setflags(write=False)
            object.__setattr__(self, "depth_m", depth)
        if self.gravity is not None:
            g = _parse_gravity(self.gravity)
            if g is None:
                raise ValueError(f"gravity must be three finite numbers, not all zero (camera axes), got "
                                 f"{self.gravity!r}")
            object.__setattr__(self, "gravity", g)
        if self.world is not None:
            world = np.array(self.world, dtype=np.float64)
            if world.shape != (NUM_LANDMARKS, 5):
                raise ValueError(f"world must have shape (33, 5) ([x, y, z] metres, visibility, presence), "
                                 f"got {world.shape}")
            partial = np.isnan(world).any(axis=1) & ~np.isnan(world).all(axis=1)
            if partial.any() or np.isinf(world).any():
                i = int(np.flatnonzero(partial | np.isinf(world).any(axis=1))[0])
                raise ValueError(f"world[{i}] ({LANDMARK_NAMES[i]}) must be five finite numbers, or NaN as a "
                                 f"whole row (unknown), got {world[i].tolist()}")
            world.setflags(write=False)
            object.__setattr__(self, "world", world)

    def own_person(self) -> int | None:
        """The track id of the frame's own person: the one of ``people`` whose landmarks are the frame's (the
        one followed longest); None without ``people`` or when none is."""
        if self.landmarks is None:
            return None
        return next((p.id for p in self.people or () if np.array_equal(p.landmarks, self.landmarks,
                                                                        equal_nan=True)), None)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LandmarkFrame):
            return NotImplemented
        if (self.seq, self.t, self.extra, self.gravity) != (other.seq, other.t, other.extra, other.gravity):
            return False
        if self.people != other.people:
            return False
        for mine, theirs in ((self.depth_m, other.depth_m), (self.world, other.world)):
            if (mine is None) != (theirs is None) or (
                    mine is not None and not np.array_equal(mine, theirs, equal_nan=True)):
                return False
        if self.landmarks is None or other.landmarks is None:
            return self.landmarks is None and other.landmarks is None
        return bool(np.array_equal(self.landmarks, other.landmarks, equal_nan=True))

    __hash__ = None  # type: ignore[assignment]

    def to_json(self) -> dict:
        lms = None if self.landmarks is None else _rows_json(self.landmarks)
        out: dict[str, Any] = {"seq": self.seq, "t": self.t, "landmarks": lms}
        if self.depth_m is not None:
            out["depth_m"] = [None if np.isnan(v) else float(v) for v in self.depth_m]
        if self.gravity is not None:
            out["gravity"] = list(self.gravity)
        if self.world is not None:
            out["world"] = _rows_json(self.world)
        if self.people is not None:
            out["people"] = [p.to_json() for p in self.people]
        for k, v in self.extra.items():
            out.setdefault(k, v)
        return out

    @classmethod
    def from_json(cls, obj: Any, invalid: list | None = None) -> LandmarkFrame:
        """Parse a frame object; raises ValueError naming what is wrong. A landmark (or world landmark, or a
        person's) whose visibility or presence is outside [0, 1] is unknown (a NaN row, as null is), and
        (landmark, field, value) for each such value is appended to ``invalid`` when given."""
        if not isinstance(obj, dict):
            raise ValueError("a frame line must be a JSON object")
        seq = obj.get("seq")
        if not isinstance(seq, int) or isinstance(seq, bool) or seq < 0:
            raise ValueError(f"seq must be a non-negative integer, got {seq!r}")
        t = obj.get("t")
        if not _is_number(t):
            raise ValueError(f"t must be a finite number of seconds, got {t!r}")
        if "landmarks" not in obj:
            raise ValueError("the key 'landmarks' is missing (use null for no person)")
        raw = obj["landmarks"]
        found: list = []
        arr = _parse_rows(raw, "landmarks", "[x, y, z, visibility, presence]", found)
        depth = _parse_depth_m(obj.get("depth_m"))
        gravity = _parse_gravity(obj.get("gravity"))
        world = _parse_rows(obj.get("world"), "world", "[x, y, z, visibility, presence] (metres)", found)
        people = _parse_people(obj["people"], found) if obj.get("people") is not None else None
        known = ("seq", "t", "landmarks") + (("depth_m",) if depth is not None else ()) + (
            ("gravity",) if gravity is not None else ()) + (("world",) if "world" in obj else ()) + (
            ("people",) if people is not None else ())
        extra = {k: v for k, v in obj.items() if k not in known}
        frame = cls(seq, float(t), arr, extra, depth, gravity, world, people)
        if invalid is not None:
            invalid += found
        return frame


def _rows_json(rows: np.ndarray) -> list:
    """33 rows of five numbers as JSON: a row with an unknown value is ``null``."""
    return [None if np.isnan(row).any() else [float(v) for v in row] for row in rows]


def _parse_rows(raw: Any, key: str, what: str, invalid: list | None = None) -> np.ndarray | None:
    """A frame's ``landmarks`` or ``world``: 33 entries of five finite numbers or null, as (33, 5) float64 with
    NaN rows; None when absent/null. Raises ValueError naming the key and the entry. An entry whose visibility
    or presence is outside [0, 1] is unknown (a NaN row) and listed in ``invalid`` as (landmark, field, value)."""
    if raw is None:
        return None
    if not isinstance(raw, list) or len(raw) != NUM_LANDMARKS:
        n = len(raw) if isinstance(raw, list) else type(raw).__name__
        raise ValueError(f"{key} must be a list of 33 entries or null, got {n}")
    arr = np.full((NUM_LANDMARKS, 5), np.nan)
    for i, lm in enumerate(raw):
        if lm is None or _non_finite(lm):
            continue   # unknown; NaN or Infinity (not JSON, but some writers emit it) is read as null is
        if not isinstance(lm, list) or len(lm) != 5 or not all(_is_number(v) for v in lm):
            label = "landmark" if key == "landmarks" else key
            raise ValueError(f"{label} {i} ({LANDMARK_NAMES[i]}) must be {what} finite numbers or null, got {lm!r}")
        bad = _out_of_range(lm)
        if bad:        # not a probability: the landmark is unknown, as with NaN; counted, not silent
            if invalid is not None:
                label = "landmark" if key == "landmarks" else key
                invalid += [(f"{label} {i} ({LANDMARK_NAMES[i]})", name, v) for name, v in bad]
            continue
        arr[i] = lm
    return arr


def _parse_depth_m(raw: Any) -> np.ndarray | None:
    """A frame's ``depth_m`` (33 metres or null each) as (33,) float64 with NaN, or None when absent/null."""
    if raw is None:
        return None
    if not isinstance(raw, list) or len(raw) != NUM_LANDMARKS:
        n = len(raw) if isinstance(raw, list) else type(raw).__name__
        raise ValueError(f"depth_m must be a list of 33 depths in metres (null where unknown), got {n}")
    depth = np.full(NUM_LANDMARKS, np.nan)
    for i, v in enumerate(raw):
        if v is None:
            continue
        if not _is_number(v) or v <= 0:
            raise ValueError(f"depth_m {i} ({LANDMARK_NAMES[i]}) must be a positive number of metres or null, "
                             f"got {v!r}")
        depth[i] = v
    return depth


def _parse_gravity(raw: Any) -> tuple[float, float, float] | None:
    """Three finite numbers, not all zero, as a tuple of floats; None for anything else."""
    if not isinstance(raw, (list, tuple)) or len(raw) != 3 or not all(_is_number(v) for v in raw):
        return None
    g = (float(raw[0]), float(raw[1]), float(raw[2]))
    return g if any(g) else None


@dataclass(frozen=True)
class RecordingProblem:
    """A frame line that could not be read; the reader skips it and goes on."""

    path: str
    line: int
    message: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.message}"


class FrameStream:
    """A recording's frames (and problems in place of bad lines), read lazily; ``invalid`` counts the
    visibility and presence values outside [0, 1] met so far (:class:`InvalidValues`). When the stream ends
    (or is closed) with any, an :class:`InvalidLandmarkValues` warning says how many and where the first is."""

    def __init__(self, fh: BinaryIO, path: str) -> None:
        self.invalid = InvalidValues(path)
        self._gen = _frames(fh, path, self.invalid)
        self._reported = False

    def __iter__(self) -> FrameStream:
        return self

    def __next__(self) -> LandmarkFrame | RecordingProblem:
        try:
            return next(self._gen)
        except StopIteration:
            self._report()
            raise

    def close(self) -> None:
        self._gen.close()
        self._report()

    def _report(self) -> None:
        if self.invalid and not self._reported:
            self._reported = True
            warnings.warn(InvalidLandmarkValues(str(self.invalid)), stacklevel=3)


def iter_recording(path: str | os.PathLike) -> tuple[RecordingHeader, FrameStream]:
    """Open a recording: its header and a lazy stream of frames, with problems in place of bad lines (and
    landmarks with visibility or presence outside [0, 1] read as unknown, counted in ``stream.invalid``)."""
    fh = _open(path)
    try:
        first = fh.readline(MAX_LINE_BYTES + 1)
        if _too_long(first):
            raise RecordingError(f"{path}:1: the first line is {_longer()}: not a landmark recording (its "
                                 "header line is a few hundred bytes)")
        header = _parse_header(first, str(path))
    except BaseException:
        fh.close()
        raise
    return header, FrameStream(fh, str(path))


def read_recording(path: str | os.PathLike) -> tuple[RecordingHeader, list[LandmarkFrame], list[RecordingProblem]]:
    """Read a whole recording: header, the frames that could be read, and the problems found."""
    header, stream = iter_recording(path)
    frames: list[LandmarkFrame] = []
    problems: list[RecordingProblem] = []
    for item in stream:
        (problems if isinstance(item, RecordingProblem) else frames).append(item)
    return header, frames, problems


def write_recording(path: str | os.PathLike, header: RecordingHeader, frames: Iterable[LandmarkFrame]) -> int:
    """Write a whole recording; returns the number of frames written."""
    with RecordingWriter(path, header) as writer:
        for frame in frames:
            writer.write(frame)
        return writer.count


class RecordingWriter:
    """Append frames to a recording as they come (flushes each line so a crash loses at most one)."""

    def __init__(self, path: str | os.PathLike, header: RecordingHeader) -> None:
        self.path = Path(path)
        self._fh: TextIO = open(self.path, "w", encoding="utf-8")
        self._fh.write(dumps(header.to_json()) + "\n")
        self.count = 0

    def write(self, frame: LandmarkFrame) -> None:
        self._fh.write(dumps(frame.to_json()) + "\n")
        self._fh.flush()
        self.count += 1

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def dumps(obj: Any) -> str:
    """Compact JSON without NaN or Infinity (which are not JSON)."""
    return json.dumps(obj, separators=(", ", ": "), allow_nan=False)


def _open(path: str | os.PathLike) -> BinaryIO:
    try:
        return open(path, "rb")
    except FileNotFoundError as exc:
        raise RecordingError(f"{path}: no such landmark recording") from exc
    except OSError as exc:
        raise RecordingError(f"{path}: cannot open: {exc.strerror}") from exc


def _parse_header(raw: bytes, path: str) -> RecordingHeader:
    try:
        line = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RecordingError(f"{path}:1: not UTF-8 text ({exc.reason})") from exc
    line = line.removeprefix("\ufeff")   # a byte-order mark some editors write: not part of the JSON
    if not line.strip(JSON_WHITESPACE):
        raise RecordingError(f"{path}:1: empty file; a recording starts with a header line "
                             f'{{"format": "{FORMAT}", "version": {VERSION}, ...}}')
    try:
        obj = json.loads(line)
        return RecordingHeader.from_json(obj)
    except (json.JSONDecodeError, ValueError) as exc:
        raise RecordingError(f"{path}:1: bad header: {exc}") from exc
    except RecursionError:
        raise RecordingError(f"{path}:1: bad header: JSON nested too deeply to be a header") from None


JSON_WHITESPACE = " \t\r\n"


def _too_long(raw: bytes) -> bool:
    return len(raw) > MAX_LINE_BYTES


def _longer() -> str:
    return f"longer than {MAX_LINE_BYTES} bytes"


def _bounded_lines(fh: BinaryIO) -> Iterator[bytes]:
    """The file's lines, each read with at most MAX_LINE_BYTES + 1 bytes (a longer one comes out cut, and
    is the last)."""
    while True:
        raw = fh.readline(MAX_LINE_BYTES + 1)
        if not raw:
            return
        yield raw
        if _too_long(raw):
            return


def _frames(fh: BinaryIO, path: str, invalid: InvalidValues) -> Iterator[LandmarkFrame | RecordingProblem]:
    with fh:
        for lineno, raw in enumerate(_bounded_lines(fh), start=2):
            if _too_long(raw):
                yield RecordingProblem(path, lineno, f"line {_longer()} (a frame line is a few kB); the rest "
                                                     "of the file is not read")
                return
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                yield RecordingProblem(path, lineno, f"not UTF-8 text ({exc.reason})")
                continue
            if not line.strip(JSON_WHITESPACE):
                continue  # a blank line (only JSON's whitespace: a control character is a problem line)
            found: list = []
            try:
                frame = LandmarkFrame.from_json(json.loads(line), found)
            except json.JSONDecodeError as exc:
                yield RecordingProblem(path, lineno, f"not valid JSON: {exc.msg} at column {exc.colno}")
            except ValueError as exc:
                yield RecordingProblem(path, lineno, str(exc))
            except RecursionError:
                yield RecordingProblem(path, lineno, "JSON nested too deeply to be a frame")
            else:
                invalid.add(lineno, found)
                yield frame
