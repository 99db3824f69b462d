"""A replay none of whose frames can be read ends with a message that says so and what to do; before, it said
"the recording has no readable frames after 0 frames (set source.loop=true ...)": looping a file that has no
readable frame only repeats the errors (what `posed config check --source` printed for one 8000x6000 image)."""

from __future__ import annotations

import struct

import cv2
import numpy as np
import pytest

from posed import hal


def test_only_unreadable_images_end_without_advising_loop(tmp_path):
    ok, png = cv2.imencode(".png", np.zeros((4, 4, 3), np.uint8))
    assert ok
    data = bytearray(png.tobytes())
    data[16:24] = struct.pack(">II", 8000, 6000)          # IHDR says 8000x6000: above the limit, never decoded
    (tmp_path / "a.png").write_bytes(bytes(data))
    (tmp_path / "b.png").write_bytes(b"not an image at all")
    errors = []
    with hal.open_source(f"file:{tmp_path}?realtime=false") as src:
        with pytest.raises(hal.EndOfStream) as end:
            for _ in range(5):
                try:
                    src.read(2.0)
                except hal.SourceCorrupt as exc:
                    errors.append(str(exc))
    assert len(errors) == 2
    text = str(end.value)
    assert "no readable frames" in text and "2 could not be used" in text and "replace or re-record" in text
    assert "loop" not in text
