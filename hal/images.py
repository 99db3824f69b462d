"""Replay of a folder of images (or one image file), in natural name order (img_2 before img_10).

Times come from the folder's ``timestamps.jsonl`` sidecar, else from ``index / source.fps``. An image that
does not decode raises SourceCorrupt naming the file; the next read goes on with the next image.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import cv2
import numpy as np

from hal.config import SourceConfig
from hal.errors import SourceCorrupt, SourceNotFound
from hal.replay import MediaEnd, ReplaySource, as_bgr

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
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if image is None or image.size == 0:
            self.count("corrupt")
            raise SourceCorrupt(f"{path}: cannot decode this image (corrupt or not an image); skipping it — "
                                "replace or delete the file", self.name)
        image = np.ascontiguousarray(as_bgr(image))
        if self.size is None:
            self.size = (int(image.shape[1]), int(image.shape[0]))
        return image, index, None
