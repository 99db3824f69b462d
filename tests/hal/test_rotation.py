"""A phone video with a rotation tag plays upright: real portrait frames stored as landscape pixels with a
90-degree display matrix in the MP4 (as a phone writes them) come out of hal as the upright frames."""

from __future__ import annotations

import struct

import cv2
import numpy as np

from posed import hal


def rotation_tagged_mp4(path, frames, fps: float = 5.0) -> None:
    """Write ``frames`` (upright, H x W) as landscape pixels (turned 90 degrees counter-clockwise) and tag the
    MP4's track header with the display matrix that turns them back (rotation 90)."""
    land = [cv2.rotate(f, cv2.ROTATE_90_COUNTERCLOCKWISE) for f in frames]
    h, w = land[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in land:
        vw.write(f)
    vw.release()
    data = bytearray(path.read_bytes())
    i = data.find(b"tkhd")
    assert i > 0, "no track header in the MP4 OpenCV wrote"
    version = data[i + 4]
    # tkhd: version+flags, times/track id/duration (v0: 20 bytes, v1: 32), reserved 8, layer, group, volume,
    # reserved (2 each), then the 3x3 matrix (16.16 fixed point, last column 2.30)
    off = i + 4 + 4 + (32 if version == 1 else 20) + 8 + 8
    assert struct.unpack(">9i", data[off:off + 36]) == (0x10000, 0, 0, 0, 0x10000, 0, 0, 0, 0x40000000)
    data[off:off + 36] = struct.pack(">9i", 0, 0x10000, 0, -0x10000, 0, 0, 0, 0, 0x40000000)
    path.write_bytes(bytes(data))


def test_a_rotation_tagged_video_plays_upright(tmp_path, squat_frames):
    upright = squat_frames[:6]                      # 720 x 1280 portrait, real
    path = tmp_path / "phone.mp4"
    rotation_tagged_mp4(path, upright)
    with hal.open_source(f"file:{path}?realtime=false") as src:
        info = src.info
        got = [src.read(timeout_s=2.0).image for _ in upright]
    assert (info["width"], info["height"], info["rotation"]) == (720, 1280, 90), info
    for a, b in zip(got, upright, strict=True):
        assert a.shape == b.shape
        # the same picture up to MPEG-4 compression; turned the wrong way it would not even have this shape,
        # and flipped upside down it differs by far more
        assert float(np.abs(a.astype(int) - b.astype(int)).mean()) < 6.0
        assert float(np.abs(a.astype(int) - b[::-1, ::-1].astype(int)).mean()) > 20.0
