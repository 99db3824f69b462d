"""Replay of a folder of images (or one image file), in natural name order (img_2 before img_10).

Times come from the folder's ``timestamps.jsonl`` sidecar, else from ``index / source.fps``. An image that
does not decode raises SourceCorrupt naming the file; the next read goes on with the next image. So does an
image larger than ``Source.max_pixels``, and so does an image whose size cannot be read from its header
(:func:`hal.image_header.header_size`: PNG, JPEG, BMP, WebP, PNM, TIFF): only an image whose size was read and
found within the limit is ever decoded, so a crafted header cannot make the decoder allocate gigabytes.
An image is turned upright by its EXIF orientation (phones store landscape pixels with a "turn by 90" tag);
grey, 16-bit and RGBA images come as 8-bit BGR.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import cv2
import numpy as np

from posed.hal.config import SourceConfig
from posed.hal.errors import SourceCorrupt, SourceNotFound
from posed.hal.image_header import header_size
from posed.hal.replay import MediaEnd, ReplaySource, as_bgr
from posed.hal.resize import MAX_DECODE_PIXELS

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm", ".pnm")


def _natural_key(name: str) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", name)]


def list_images(folder: str | os.PathLike) -> list[Path]:
    """The image files of a folder in natural order."""
    files = [p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS]
    return sorted(files, key=lambda p: _natural_key(p.name))


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
        size = header_size(path)                 # decoded only when known and within the limit
        if size is None:
            self.count("corrupt")
            raise SourceCorrupt(f"{path}: cannot decode this image: its size cannot be read from its header "
                                "(corrupt, crafted, or not a PNG, JPEG, BMP, WebP, PNM or TIFF image), and an "
                                "image of unknown size is never decoded; skipping it — replace or delete the "
                                "file", self.name)
        self._check_size(path, *size)
        # IMREAD_COLOR turns the image upright by its EXIF orientation (a phone's photo: landscape pixels tagged
        # "turn by 90"), as `posed landmarks` reads one; IMREAD_UNCHANGED ignored the tag and replayed it
        # sideways (a standing person lying). ANYDEPTH keeps a 16-bit image's precision for as_bgr.
        image = cv2.imread(str(path), cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH)
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
        limit = self.max_pixels or MAX_DECODE_PIXELS
        if width * height > limit:
            self.count("corrupt")
            raise SourceCorrupt(f"{path}: a {width}x{height} image ({width * height} pixels) is larger than the "
                                f"{limit}-pixel frames this pipeline takes; skipping it", self.name,
                                pixels=width * height)
