"""Replay of an image folder (and of one image): order, timing from fps, a corrupt image in the middle."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from posed import hal
from posed.hal.images import ImageFolderSource


@pytest.fixture()
def folder(tmp_path, squat_frames):
    d = tmp_path / "frames"
    d.mkdir()
    for i in (0, 1, 2, 10, 11):  # natural order must put 2 before 10
        cv2.imwrite(str(d / f"img_{i}.png"), cv2.resize(squat_frames[i], (180, 320)))
    (d / "notes.txt").write_text("ignored")
    return d


def test_folder_in_natural_order_timed_by_fps(folder):
    src = hal.open_source(f"file:{folder}?realtime=false&fps=10")
    assert isinstance(src, ImageFolderSource)
    with src:
        frames = [src.read() for _ in range(5)]
        with pytest.raises(hal.EndOfStream):
            src.read()
        assert src.info["frame_count"] == 5 and src.info["fps"] == 10
    expected = [cv2.imread(str(folder / f"img_{i}.png")) for i in (0, 1, 2, 10, 11)]
    assert all(np.array_equal(f.image, e) for f, e in zip(frames, expected, strict=True))
    assert [f.seq for f in frames] == [0, 1, 2, 3, 4]
    assert np.allclose(np.diff([f.t for f in frames]), 0.1, atol=1e-9)


def test_corrupt_image_is_named_and_skipped(folder):
    (folder / "img_2.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    with hal.open_source(f"file:{folder}?realtime=false") as src:
        a, b = src.read(), src.read()
        with pytest.raises(hal.SourceCorrupt, match=r"img_2\.png: cannot decode this image"):
            src.read()
        c = src.read()
        assert src.info["corrupt"] == 1
    assert [a.seq, b.seq, c.seq] == [0, 1, 3]  # the gap shows the lost frame


def test_grey_and_alpha_images_become_bgr(tmp_path):
    d = tmp_path / "mixed"
    d.mkdir()
    cv2.imwrite(str(d / "a.png"), np.full((40, 30), 77, np.uint8))
    cv2.imwrite(str(d / "b.png"), np.dstack([np.full((40, 30), v, np.uint8) for v in (1, 2, 3, 200)]))
    cv2.imwrite(str(d / "c.png"), np.full((40, 30, 3), 60000, np.uint16))
    with hal.open_source(f"file:{d}?realtime=false") as src:
        a, b, c = src.read(), src.read(), src.read()
    assert a.image.shape == b.image.shape == c.image.shape == (40, 30, 3)
    assert a.image.dtype == np.uint8 and int(a.image[0, 0, 0]) == 77
    assert b.image[0, 0].tolist() == [1, 2, 3]
    assert c.image[0, 0].tolist() == [60000 >> 8] * 3


def test_single_image_and_empty_folder(tmp_path, folder):
    with hal.open_source(f"file:{folder / 'img_1.png'}") as src:
        assert src.read().image.shape == (320, 180, 3)
        with pytest.raises(hal.EndOfStream):
            src.read()
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(hal.SourceNotFound, match="holds no images"):
        hal.open_source(f"file:{empty}").open()
