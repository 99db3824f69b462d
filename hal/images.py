"""Replay of a folder of images (or one image file), in natural name order (img_2 before img_10).

Times come from the folder's ``timestamps.jsonl`` sidecar, else from ``index / source.fps``. An image that
does not decode raises SourceCorrupt naming the file; the next read goes on with the next image. So does an
image larger than ``Source.max_pixels``: PNG, JPEG and BMP sizes are read from the file's header
(:func:`header_size`), so such an image is never decoded; other formats are checked after decoding.
"""

from __future__ import annotations

import os
import re
import struct
from pathlib import Path

import cv2
import numpy as np

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceNotFound
from posed.hal.replay import MediaEnd, ReplaySource, as_bgr

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pnm")


def _natural_key(name: str) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", name)]


def list_images(folder: str | os.PathLike) -> list[Path]:
    """The image files of a folder in natural order."""
    files = [p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS]
    return sorted(files, key=lambda p: _natural_key(p.name))


def header_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """(width, height) from a PNG, JPEG or BMP header without decoding the pixels; None for other formats
    or a header that cannot be read."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(32)
            if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR":
                w, h = struct.unpack(">II", head[16:24])
                return int(w), int(h)
            if head.startswith(b"BM") and len(head) >= 26:
                w, h = struct.unpack("<ii", head[18:26])
                return abs(int(w)), abs(int(h))
            if head.startswith(b"\xff\xd8"):
                return _jpeg_size(fh)
    except (OSError, struct.error):
        return None
    return None


def _jpeg_size(fh) -> tuple[int, int] | None:
    """Walk the JPEG markers up to the first start-of-frame (SOF0..SOF15 but DHT, JPG, DAC)."""
    fh.seek(2)
    for _ in range(10000):
        marker = fh.read(2)
        if len(marker) < 2 or marker[0] != 0xFF:
            return None
        kind = marker[1]
        if kind in (0xD8, 0x01) or 0xD0 <= kind <= 0xD7:
            continue
        length = struct.unpack(">H", fh.read(2))[0]
        if 0xC0 <= kind <= 0xCF and kind not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">xHH", fh.read(5))
            return int(w), int(h)
        fh.seek(length - 2, os.SEEK_CUR)
    return None


class ImageFolderSource(ReplaySource):
    """Frames of the images of a folder, or of a single image file (one frame)."""

    def __init__(self, config: SourceConfig, path: str, **kw) -> None:
        super().__init__(config, path, **kw)
        self.files: list[Path] = []
        self._next = 0

    def _open_media(self) -> None:
        p = Path(self.path)
        if p.is_dir():
            self.files = list_images(p)
            if not self.files:
                raise SourceNotFound(f"{self.path}: the folder holds no images ({', '.join(IMAGE_EXTENSIONS)})",
                                     self.name)
        elif p.is_file():
            self.files = [p]
        else:
            raise SourceNotFound(f"{self.path}: no such image or folder; check source.path or the file: URI",
                                 self.name)
        self.nominal_fps = 0.0
        self._next = 0

    def _close_media(self) -> None:
        self._next = 0

    def _rewind(self) -> None:
        self._next = 0

    def _frame_period(self) -> float:
        if self.sidecar is not None and self.sidecar.fps > 0:
            return 1.0 / self.sidecar.fps
        return 1.0 / self.config.fps

    def _describe(self) -> dict:
        out = super()._describe()
        out.update(fps=self.sidecar.fps if self.sidecar and self.sidecar.fps > 0 else self.config.fps,
                   frame_count=len(self.files))
        return out

    def _next_raw(self, deadline: float) -> tuple[np.ndarray, int, float | None]:
        if self._next >= len(self.files):
            raise MediaEnd
        index = self._next
        self._next += 1
        path = self.files[index]
        size = header_size(path) if self.max_pixels else None
        if size is not None:
            self._check_size(path, *size)
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None or image.size == 0:
            self.count("corrupt")
            raise SourceCorrupt(f"{path}: cannot decode this image (corrupt or not an image); skipping it — "
                                "replace or delete the file", self.name)
        self._check_size(path, image.shape[1], image.shape[0])
        image = np.ascontiguousarray(as_bgr(image))
        if self.size is None:
            self.size = (int(image.shape[1]), int(image.shape[0]))
        return image, index, None

    def _check_size(self, path: Path, width: int, height: int) -> None:
        if self.max_pixels and width * height > self.max_pixels:
            self.count("corrupt")
            raise SourceCorrupt(f"{path}: a {width}x{height} image ({width * height} pixels) is larger than the "
                                f"{self.max_pixels}-pixel frames this pipeline takes; skipping it", self.name,
                                pixels=width * height)
