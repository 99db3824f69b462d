"""An image file's size (width, height) in pixels read from its header, without decoding the pixels.

Formats: PNG (IHDR), JPEG (the first start-of-frame marker), BMP, WebP (VP8, VP8L, VP8X), PNM (P1..P6) and
TIFF (the first image's ImageWidth and ImageLength). The image folder source decodes only images whose size
it read here and found within its pixel limit (hal.images), so a crafted header can never make it allocate
gigabytes.

JPEG is read as libjpeg reads it: bytes that are not a marker between two segments ("extraneous bytes before
marker", e.g. three stray bytes after APP0) are skipped, as are fill bytes (0xFF repeated), so a file libjpeg
would decode always has its size read here.
"""

from __future__ import annotations

import os
import re
import struct

HEAD_BYTES = 64
JPEG_MAX_SCAN = 1 << 20         # bytes walked looking for the start-of-frame before giving up
_SOF = {k for k in range(0xC0, 0xD0)} - {0xC4, 0xC8, 0xCC}     # start-of-frame kinds (not DHT, JPG, DAC)
_STANDALONE = {0x01, *range(0xD0, 0xDA)}                         # TEM, RST0..7, SOI, EOI: no length


def header_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """(width, height) from the file's header; None for another format or a header that cannot be read."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(HEAD_BYTES)
            if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR":
                w, h = struct.unpack(">II", head[16:24])
                return int(w), int(h)
            if head.startswith(b"BM") and len(head) >= 26:
                w, h = struct.unpack("<ii", head[18:26])
                return abs(int(w)), abs(int(h))
            if head.startswith(b"\xff\xd8"):
                fh.seek(2)
                return _jpeg_size(fh.read(JPEG_MAX_SCAN))
            if head.startswith(b"RIFF") and head[8:12] == b"WEBP":
                return _webp_size(head)
            if re.match(rb"P[1-6]\s", head):
                return _pnm_size(head + fh.read(1024))
            if head[:4] in (b"II*\x00", b"MM\x00*"):
                fh.seek(0)
                return _tiff_size(fh.read(JPEG_MAX_SCAN))
    except (OSError, struct.error, ValueError, IndexError):
        return None
    return None


def _jpeg_size(data: bytes) -> tuple[int, int] | None:
    """Walk the markers after SOI up to the first start-of-frame, skipping what is not a marker."""
    i, n = 0, len(data)
    while i < n - 1:
        if data[i] != 0xFF:                      # extraneous bytes: libjpeg skips them with a warning
            i += 1
            continue
        kind = data[i + 1]
        if kind == 0xFF:                          # fill byte
            i += 1
            continue
        if kind == 0x00:                          # a stuffed 0xFF inside data: not a marker
            i += 2
            continue
        if kind in _STANDALONE:
            if kind == 0xD9:                      # EOI before any frame
                return None
            i += 2
            continue
        if i + 4 > n:
            return None
        length = struct.unpack(">H", data[i + 2:i + 4])[0]
        if kind in _SOF:
            if i + 9 > n:
                return None
            h, w = struct.unpack(">HH", data[i + 5:i + 9])
            return int(w), int(h)
        if kind == 0xDA:                          # start of scan before any frame: not a decodable JPEG
            return None
        i += 2 + length
    return None


def _webp_size(head: bytes) -> tuple[int, int] | None:
    chunk = head[12:16]
    if chunk == b"VP8 " and head[23:26] == b"\x9d\x01\x2a":
        w, h = struct.unpack("<HH", head[26:30])
        return w & 0x3FFF, h & 0x3FFF
    if chunk == b"VP8L" and head[20] == 0x2F:
        b = head[21:25]
        w = 1 + (((b[1] & 0x3F) << 8) | b[0])
        h = 1 + (((b[3] & 0x0F) << 10) | (b[2] << 2) | ((b[1] & 0xC0) >> 6))
        return w, h
    if chunk == b"VP8X":
        w = 1 + int.from_bytes(head[24:27], "little")
        h = 1 + int.from_bytes(head[27:30], "little")
        return w, h
    return None


def _pnm_size(head: bytes) -> tuple[int, int] | None:
    text = re.sub(rb"#[^\n]*", b" ", head[2:])      # comments may sit between the numbers
    m = re.match(rb"\s*(\d+)\s+(\d+)", text)
    return (int(m.group(1)), int(m.group(2))) if m else None


def _tiff_size(data: bytes) -> tuple[int, int] | None:
    order = "<" if data[:2] == b"II" else ">"
    (ifd,) = struct.unpack(order + "I", data[4:8])
    (count,) = struct.unpack(order + "H", data[ifd:ifd + 2])
    size: dict[int, int] = {}
    for k in range(count):
        tag, kind, _, value = struct.unpack(order + "HHI4s", data[ifd + 2 + 12 * k:ifd + 14 + 12 * k])
        if tag in (256, 257):
            size[tag] = struct.unpack(order + "H", value[:2])[0] if kind == 3 else struct.unpack(order + "I", value)[0]
    return (size[256], size[257]) if 256 in size and 257 in size else None
