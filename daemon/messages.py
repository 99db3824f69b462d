"""The small frozen messages the daemon's processes exchange; pixels never travel in them.

* :class:`FrameRef` (capture -> landmarks): names a slot of the shared-memory ring.
* :class:`LandmarkMsg` (landmarks -> fitting) and :class:`FitMsg` (fitting -> publisher), pickled into the
  mailboxes; ``stamps`` collects ``(mark, monotonic time)`` pairs for the per-stage timings the pose topic
  carries.
* :class:`StageHealth`: each stage's heartbeat.

``t_capture`` is the capture timestamp (seconds on the daemon's one monotonic clock) and travels end to end;
it is the only clock used for fall timing. ``t_origin`` is where latency counts from: the capture timestamp,
except for unpaced replays, whose capture timestamps follow the recording's time line while frames are read
as fast as the pipeline takes them (then it is the time the capture stage read the frame); None means
``t_capture``. Every message uses these two names (the convention: :mod:`camera_model.intrinsics`).
``intrinsics`` is always a :class:`camera_model.Intrinsics` of the frame's image, or None."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from posed.camera_model import Intrinsics
from posed.fitting import FitResult
from posed.landmarks import LandmarkFrame

STAGES = ("capture", "landmarks", "fitting", "publisher")


@dataclass(frozen=True)
class FrameRef:
    """A captured frame waiting in the shared-memory ring."""

    slot: int
    seq: int
    t_capture: float
    width: int
    height: int
    has_depth: bool = False
    intrinsics: Intrinsics | None = None   # of the frame's image, when known
    t_origin: float | None = None   # latency is measured from here (None: from t_capture); set only for
                                    # unpaced replays: the time the capture stage read the frame
    gravity: tuple[float, float, float] | None = None   # down, unit vector, colour camera axes (hal.Frame)
    scale: int = 1         # the source's frame was scaled down by this whole factor to width x height (hal.resize)
    source_size: tuple[int, int] | None = None   # (width, height) as the source delivered it; None: unscaled

    @property
    def full_size(self) -> tuple[int, int]:
        """(width, height) of the frame as the source delivered it: the pixels landmarks are reported in."""
        return self.source_size or (self.width, self.height)

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in ("slot", "seq", "t_capture", "width", "height", "has_depth")}
        out["intrinsics"] = None if self.intrinsics is None else self.intrinsics.to_json()
        out["t_origin"] = self.t_origin
        out["gravity"] = None if self.gravity is None else list(self.gravity)
        out["scale"] = self.scale
        out["source_size"] = None if self.source_size is None else list(self.source_size)
        return out

    @classmethod
    def from_json(cls, obj: dict) -> FrameRef:
        intr = obj.get("intrinsics")
        t_origin = obj.get("t_origin")
        gravity = obj.get("gravity")
        return cls(**{k: obj[k] for k in ("slot", "seq", "t_capture", "width", "height")},
                   has_depth=bool(obj.get("has_depth", False)),
                   intrinsics=None if intr is None else Intrinsics.from_json(intr),
                   t_origin=None if t_origin is None else float(t_origin),
                   gravity=None if gravity is None else tuple(float(v) for v in gravity),
                   scale=int(obj.get("scale", 1)),
                   source_size=None if obj.get("source_size") is None else tuple(int(v) for v in obj["source_size"]))


@dataclass(frozen=True)
class StageHealth:
    """Heartbeat of one stage process: when it last beat and when its current step began (None = idle)."""

    stage: str
    pid: int
    beat: float
    step_started: float | None
    frames: int
    drops: int = 0
    state: str = "running"

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, obj: dict) -> StageHealth:
        return cls(**obj)


@dataclass(frozen=True)
class LandmarkMsg:
    """2D landmarks of one frame, for the fitting stage; ``frame.depth_m`` carries the aligned depth at the
    landmarks (metres, NaN unknown) when the source had depth, else None."""

    frame: LandmarkFrame
    t_capture: float
    image_size: tuple[int, int]
    intrinsics: Intrinsics | None = None
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
    intrinsics: Intrinsics | None = None
    t_origin: float | None = None     # latency is measured from here (None: from t_capture)
    others: tuple[FitResult, ...] = ()  # the fits of the frame's other people (each with extra["person"])


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


def origin(msg: FrameRef | LandmarkMsg | FitMsg) -> float:
    """The time latency counts from for a FrameRef, LandmarkMsg or FitMsg."""
    return msg.t_capture if msg.t_origin is None else msg.t_origin
