"""The timestamps sidecar of a recorded video or image folder: ``NAME.timestamps.jsonl``.

``posed record`` writes it next to the video (``rec.mkv`` -> ``rec.timestamps.jsonl``) or inside the image
folder (``folder/timestamps.jsonl``); the replay source reads it back. JSON Lines, a header then one line per
frame in file order::

    {"format": "posed.timestamps", "version": 1, "source": "v4l2:/dev/video0", "fps": 30.0,
     "image_size": [640, 480], "intrinsics": {"fx": .., "fy": .., "cx": .., "cy": .., "width": .., "height": ..}}
    {"frame": 0, "seq": 17, "t": 0.0}
    {"frame": 1, "seq": 18, "t": 0.0334}

``frame`` is the index of the frame in the video (or the sorted image list), ``seq`` the source's frame
number, ``t`` the capture time in seconds since the first recorded frame. ``intrinsics`` may be null. A last
line cut short (the recorder was killed) is ignored; any other bad line is an error naming FILE:LINE.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from posed.camera_model import Intrinsics
from posed.hal.errors import SourceCorrupt

FORMAT = "posed.timestamps"
VERSION = 1


def sidecar_path(media: str | os.PathLike) -> Path:
    """Where the sidecar of a video file or image folder lives."""
    p = Path(media)
    if p.is_dir():
        return p / "timestamps.jsonl"
    return p.with_suffix(".timestamps.jsonl")


@dataclass(frozen=True)
class Timestamps:
    """A sidecar read back: per file frame index, the source's seq and the capture time (s from the first)."""

    path: str
    source: str
    fps: float
    image_size: tuple[int, int] | None
    intrinsics: Intrinsics | None
    by_frame: dict[int, tuple[int, float]] = field(default_factory=dict)

    def lookup(self, frame: int) -> tuple[int, float] | None:
        return self.by_frame.get(frame)


MAX_LINE_BYTES = 65536     # a sidecar line is under 100 bytes, the header under 1 kB


def _read_lines(path: Path, name: str) -> list[str]:
    """The file's lines (without newlines), each read with at most MAX_LINE_BYTES + 1 bytes: a longer line
    (a 2 GB line, /dev/zero) is SourceCorrupt, not read whole."""
    lines: list[str] = []
    with path.open("rb") as fh:
        while True:
            raw = fh.readline(MAX_LINE_BYTES + 1)
            if not raw:
                break
            if len(raw) > MAX_LINE_BYTES:
                raise SourceCorrupt(f"{name}:{len(lines) + 1}: line longer than {MAX_LINE_BYTES} bytes: not a "
                                    "timestamps sidecar; delete or fix the file", name)
            try:
                lines.append(raw.decode("utf-8").rstrip("\n"))
            except UnicodeDecodeError:
                raise SourceCorrupt(f"{name}:{len(lines) + 1}: not UTF-8 text; delete or fix the file",
                                    name) from None
    return lines or [""]


def read_sidecar(path: str | os.PathLike) -> Timestamps:
    """Parse a sidecar; raises SourceCorrupt naming FILE:LINE for a bad line."""
    path = Path(path)
    name = str(path)
    lines = _read_lines(path, name)
    try:
        head = json.loads(lines[0])
    except (json.JSONDecodeError, IndexError):
        raise SourceCorrupt(f"{name}:1: not a timestamps sidecar header (JSON expected); delete or fix the file",
                            name) from None
    if not isinstance(head, dict) or head.get("format") != FORMAT:
        raise SourceCorrupt(f"{name}:1: header format must be {FORMAT!r}; delete or fix the file", name)
    if head.get("version") != VERSION:
        raise SourceCorrupt(f"{name}:1: version {head.get('version')!r} is not supported (expected {VERSION})",
                            name)
    intr = head.get("intrinsics")
    size = head.get("image_size")
    by_frame: dict[int, tuple[int, float]] = {}
    last = len(lines) - 1
    while last > 0 and not lines[last].strip():
        last -= 1
    for no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
            by_frame[int(obj["frame"])] = (int(obj["seq"]), float(obj["t"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            if no - 1 == last:  # a last line cut short by a killed recorder
                break
            raise SourceCorrupt(f"{name}:{no}: bad frame line ({exc}); expected "
                                '{"frame": i, "seq": n, "t": seconds}', name) from None
    return Timestamps(
        path=name, source=str(head.get("source", "")), fps=float(head.get("fps") or 0.0),
        image_size=tuple(size) if isinstance(size, list) and len(size) == 2 else None,
        intrinsics=Intrinsics.from_json(intr) if isinstance(intr, dict) else None, by_frame=by_frame)


class SidecarWriter:
    """Writes a sidecar line by line (flushed per frame, so a killed recorder leaves a usable file)."""

    def __init__(self, path: str | os.PathLike, source: str, fps: float, image_size: tuple[int, int],
                 intrinsics: Intrinsics | None) -> None:
        self.path = Path(path)
        self._fh: TextIO | None = self.path.open("w", encoding="utf-8")
        head: dict[str, Any] = {"format": FORMAT, "version": VERSION, "source": source, "fps": fps,
                                "image_size": list(image_size),
                                "intrinsics": intrinsics.to_json() if intrinsics else None}
        self._write(head)

    def _write(self, obj: dict) -> None:
        assert self._fh is not None
        self._fh.write(json.dumps(obj, separators=(",", ":")) + "\n")
        self._fh.flush()

    def add(self, frame: int, seq: int, t: float) -> None:
        self._write({"frame": frame, "seq": seq, "t": round(t, 6)})

    def keep(self, frames: int) -> None:
        """Cut the file to its header and the first ``frames`` frame lines (the video holds no more: a disk
        that filled up); cutting needs no free space."""
        self.close()
        with self.path.open("r+b") as fh:
            for _ in range(frames + 1):
                if not fh.readline():
                    return
            fh.truncate()

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None
