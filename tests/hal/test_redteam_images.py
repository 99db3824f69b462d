"""An image folder with a huge image and a broken one: sizes read from PNG/JPEG/BMP headers, an image larger
than ``max_pixels`` skipped as SourceCorrupt (with its pixel count) before it is decoded, reading goes on."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from posed import hal
from posed.hal import SourceCorrupt


@pytest.mark.parametrize("ext", ["png", "jpg", "bmp"])
def test_header_size_without_decoding(tmp_path, ext):
    from posed.hal.images import header_size

    path = tmp_path / f"a.{ext}"
    cv2.imwrite(str(path), np.zeros((37, 53, 3), np.uint8))
    assert header_size(path) == (53, 37)
    (tmp_path / f"b.{ext}").write_bytes(b"garbage")
    assert header_size(tmp_path / f"b.{ext}") is None


def test_oversized_image_is_skipped_and_reading_goes_on(tmp_path, squat_frames):
    cv2.imwrite(str(tmp_path / "img_1.png"), squat_frames[0])
    cv2.imwrite(str(tmp_path / "img_2.png"), np.zeros((3000, 3000, 3), np.uint8))
    (tmp_path / "img_3.png").write_bytes(b"\x89PNG\r\n\x1a\nbroken")
    cv2.imwrite(str(tmp_path / "img_4.png"), squat_frames[1])
    src = hal.open_source(f"file:{tmp_path}?realtime=false")
    src.open()
    src.max_pixels = 1280 * 720
    try:
        first = src.read(1.0)
        with pytest.raises(SourceCorrupt, match="3000x3000") as big:
            src.read(1.0)
        assert big.value.pixels == 9_000_000
        with pytest.raises(SourceCorrupt, match="cannot decode"):
            src.read(1.0)
        last = src.read(1.0)
        assert np.array_equal(first.image, squat_frames[0]) and np.array_equal(last.image, squat_frames[1])
        assert src.info["corrupt"] == 2
    finally:
        src.close()
