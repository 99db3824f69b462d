"""A RealSense frameset that librealsense fails on (its data, the alignment to colour) is one bad frame, not
the end of the capture: before, its RuntimeError escaped ``read()`` (not a SourceError), so the daemon's
capture stage died on it and the supervisor restarted the stage until it gave up (exit 70)."""

from __future__ import annotations

from posed import hal
from posed.hal.config import SourceConfig
from posed.hal.realsense import RealSenseSource
from posed.hal.rs_playback import PlaybackPipeline
from tests.hal.conftest import DB3_FRAMES


class BrokenFrameset:
    """A frameset whose colour frame librealsense cannot hand over."""

    def __init__(self, inner):
        self.inner = inner

    def get_color_frame(self):
        raise RuntimeError("simulated: frame didn't arrive within the expected size (USB transfer cut short)")

    def __getattr__(self, name):
        return getattr(self.inner, name)


class OneBadFrameset(PlaybackPipeline):
    delivered = 0

    def try_wait_for_frames(self, timeout_ms=5000):
        ok, frames = super().try_wait_for_frames(timeout_ms)
        if ok:
            type(self).delivered += 1
            if type(self).delivered == 3:
                return True, BrokenFrameset(frames)
        return ok, frames


def test_a_frameset_librealsense_fails_on_is_skipped_and_named(squat_db3):
    OneBadFrameset.delivered = 0
    src = RealSenseSource(SourceConfig(realtime=False), playback=str(squat_db3.path),
                          pipeline_factory=lambda rs: OneBadFrameset(rs))
    frames, errors = [], []
    with src:
        while True:
            try:
                frames.append(src.read(2.0))
            except hal.EndOfStream:
                break
            except hal.SourceCorrupt as exc:
                errors.append(str(exc))
                assert "record the file again" in exc.fix
        info = src.info
    assert len(errors) == 1 and "a frame could not be read" in errors[0] and "USB transfer cut short" in errors[0]
    assert str(squat_db3.path) in errors[0]
    assert info["corrupt"] == 1
    assert len(frames) == DB3_FRAMES - 1                                 # every other frame, in order
    assert [f.seq for f in frames] == sorted(f.seq for f in frames)


def test_black_frames_of_a_covered_realsense_are_said_and_skipped(tmp_path, squat_frames):
    # a RealSense whose lens is covered sends black colour frames: they show nobody, and the daemon went on
    # "running" on them without a word (no person is not the same as no picture)
    import cv2
    import numpy as np

    from posed.camera_model import Intrinsics
    from posed.hal.db3 import Db3Writer

    k = Intrinsics(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240)
    path = tmp_path / "covered.db3"
    with Db3Writer(path, k, 10.0) as w:
        for i in range(6):
            image = np.zeros((240, 320, 3), np.uint8) if i in (2, 3) else cv2.resize(squat_frames[i], (320, 240))
            w.write(image, None, 1000.0 + 100.0 * i, i)
    frames, errors = [], []
    with hal.open_source(f"file:{path}?realtime=false") as src:
        while True:
            try:
                frames.append(src.read(2.0))
            except hal.EndOfStream:
                break
            except hal.SourceCorrupt as exc:
                errors.append(exc)
        info = src.info
    assert [f.seq for f in frames] == [0, 1, 4, 5]
    assert len(errors) == 2 and all("blank frames" in str(e) and "black" in str(e) for e in errors)
    assert all("uncover the camera's lens" in e.fix for e in errors)
    assert info["blank"] == 2
