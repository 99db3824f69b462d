"""A phone photo in an image folder: landscape pixels with an EXIF tag saying "turn by 90" replay upright, as
the same photo does in `posed landmarks` (OpenCV applies the tag when it decodes in colour); before, the
replay ignored the tag and the daemon saw a standing person lying on their side."""

from __future__ import annotations

import struct

import cv2
import numpy as np

from posed import hal


def with_orientation(jpeg: bytes, orientation: int) -> bytes:
    """``jpeg`` with an APP1 Exif segment right after SOI holding only the Orientation tag (0x0112)."""
    tiff = b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", 1) \
        + struct.pack("<HHIHH", 0x0112, 3, 1, orientation, 0) + struct.pack("<I", 0)
    payload = b"Exif\x00\x00" + tiff
    app1 = b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    assert jpeg[:2] == b"\xff\xd8"
    return jpeg[:2] + app1 + jpeg[2:]


def test_exif_rotated_photo_replays_upright(tmp_path, squat_frames):
    upright = squat_frames[10]                                   # real frame, portrait 720x1280
    h, w = upright.shape[:2]
    assert h > w
    stored = cv2.rotate(upright, cv2.ROTATE_90_COUNTERCLOCKWISE)  # what the phone's sensor stored: landscape
    ok, jpeg = cv2.imencode(".jpg", stored, [cv2.IMWRITE_JPEG_QUALITY, 95])
    assert ok
    folder = tmp_path / "phone"
    folder.mkdir()
    (folder / "IMG_0001.jpg").write_bytes(with_orientation(jpeg.tobytes(), 6))   # 6: turn 90 clockwise
    with hal.open_source(f"file:{folder}?realtime=false") as src:
        frame = src.read(2.0)
    assert (frame.width, frame.height) == (w, h)
    assert np.abs(frame.image.astype(int) - upright.astype(int)).mean() < 4


def test_sixteen_bit_and_grey_images_still_read(tmp_path, squat_frames):
    grey = cv2.cvtColor(squat_frames[0], cv2.COLOR_BGR2GRAY)
    folder = tmp_path / "mixed"
    folder.mkdir()
    cv2.imwrite(str(folder / "a_1.png"), grey.astype(np.uint16) * 257)            # 16-bit grey
    cv2.imwrite(str(folder / "a_2.png"), squat_frames[0].astype(np.uint16) * 257)  # 16-bit colour
    with hal.open_source(f"file:{folder}?realtime=false") as src:
        first, second = src.read(2.0), src.read(2.0)
    assert np.array_equal(first.image[:, :, 0], grey) and np.array_equal(first.image[:, :, 2], grey)
    assert np.array_equal(second.image, squat_frames[0])
