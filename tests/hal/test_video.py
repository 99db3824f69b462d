"""Replay of the real squat video with real OpenCV/FFmpeg decoding: frames, timestamps, pacing, looping,
corrupt and truncated copies."""

from __future__ import annotations

import random
import time

import numpy as np
import pytest

from posed import hal
from posed.camera_model import Intrinsics
from posed.hal.config import SourceConfig
from posed.hal.video import VideoFileSource
from tests.hal.conftest import SQUAT_FPS, SQUAT_FRAMES


def drain(src: hal.Source, timeout: float = 2.0) -> tuple[list[hal.Frame], list[hal.SourceError]]:
    frames, errors = [], []
    while True:
        try:
            frames.append(src.read(timeout))
        except hal.EndOfStream:
            return frames, errors
        except hal.SourceCorrupt as exc:
            errors.append(exc)


def test_every_frame_decodes_with_pts_timestamps(squat_video, squat_frames):
    src = hal.open_source(f"file:{squat_video}?realtime=false")
    assert isinstance(src, VideoFileSource)
    with src:
        t0 = time.perf_counter()
        before = time.monotonic()
        frames, errors = drain(src)
        decode_fps = len(frames) / (time.perf_counter() - t0)
        after = time.monotonic()
        info = src.info
    assert errors == []
    assert [f.seq for f in frames] == list(range(SQUAT_FRAMES))
    assert all(np.array_equal(f.image, ref) for f, ref in zip(frames, squat_frames, strict=True))
    assert all(f.depth is None and f.depth_scale == 0.0 and f.intrinsics is None for f in frames)
    assert before <= frames[0].t <= after  # t starts at the first read, on the monotonic clock
    assert np.allclose([f.t - frames[0].t for f in frames], np.arange(SQUAT_FRAMES) / SQUAT_FPS, atol=1e-6)
    assert info["frame_count"] == SQUAT_FRAMES and info["fps"] == SQUAT_FPS and info["codec"] == "h264"
    assert (info["width"], info["height"]) == (720, 1280) and info["timestamps"] == "pts"
    print(f"squat video 720x1280 H.264 decode: {decode_fps:.0f} frames/s (shared 2-core machine)")
    # real-time replay must keep up with the video's own rate (5 frames/s); the speed itself is a benchmark
    # (posed bench hal), measured ~350 frames/s here
    assert decode_fps > SQUAT_FPS


def test_after_the_end_every_read_is_end_of_stream(squat_video):
    with hal.open_source(f"file:{squat_video}?realtime=false") as src:
        drain(src)
        with pytest.raises(hal.EndOfStream, match="loop=true"):
            src.read()
        assert src.info["state"] == "ended"


def test_realtime_pacing_and_read_timeout(squat_video):
    waits = []

    def sleep(seconds: float) -> None:  # the real sleep, recording what the source asked for
        waits.append(seconds)
        time.sleep(seconds)

    config = SourceConfig(type="file", path=str(squat_video))
    with VideoFileSource(config, str(squat_video), sleep=sleep) as src:
        t0 = time.monotonic()
        first = src.read(1.0)
        second = src.read(1.0)
        assert second.t - first.t == pytest.approx(0.2, abs=1e-6)
        assert time.monotonic() >= second.t - 1e-3
        assert time.monotonic() - t0 >= 0.2 - 1e-3  # the second frame was held back until its time
        # and no longer: the wait ends at the frame's time, at most one frame period after the first read
        assert waits and sum(waits) <= 1 / SQUAT_FPS + 1e-6
        # the next frame is due 0.2 s later: a 0.05 s read times out without losing it
        with pytest.raises(hal.SourceTimeout, match="due in"):
            src.read(0.05)
        third = src.read(1.0)
        assert third.seq == 2 and third.t - first.t == pytest.approx(0.4, abs=1e-6)


def test_time_starts_at_the_first_read_not_at_open(squat_video):
    with hal.open_source(f"file:{squat_video}") as src:
        time.sleep(0.3)  # e.g. the pipeline warming up its models
        t_read = time.monotonic()
        a, b = src.read(1.0), src.read(1.0)
        assert a.t >= t_read and b.t - a.t == pytest.approx(0.2, abs=1e-6)
        assert time.monotonic() - t_read >= 0.19  # frame 1 was not handed out at once


def test_loop_continues_seq_and_time(squat_video):
    cfg = SourceConfig(type="file", path=str(squat_video), realtime=False, loop=True)
    with hal.open_source(cfg) as src:
        frames = [src.read() for _ in range(SQUAT_FRAMES + 3)]
        assert src.info["passes"] == 1
    assert [f.seq for f in frames] == list(range(SQUAT_FRAMES + 3))
    assert np.allclose(np.diff([f.t for f in frames]), 1 / SQUAT_FPS, atol=1e-6)
    assert np.array_equal(frames[SQUAT_FRAMES].image, frames[0].image)


def test_intrinsics_from_config(squat_video):
    with hal.open_source(f"file:{squat_video}?realtime=false&fx=900&cy=600") as src:
        f = src.read()
    assert f.intrinsics == Intrinsics(fx=900.0, fy=900.0, cx=359.5, cy=600.0, width=720, height=1280)


def _corrupt_copy(src, dst, start, length, seed=1):
    data = bytearray(src.read_bytes())
    rng = random.Random(seed)
    for i in range(start, start + length):
        data[i] = rng.randrange(256)
    dst.write_bytes(bytes(data))


def test_corrupt_middle_is_a_distinct_error_and_replay_goes_on(tmp_path, squat_video, squat_frames):
    bad = tmp_path / "squat_bad.mp4"
    _corrupt_copy(squat_video, bad, 200_000, 60_000)  # ~ frames 21..30 of the 507 kB mdat
    with hal.open_source(f"file:{bad}?realtime=false") as src:
        frames, errors = drain(src)
        info = src.info
    assert len(errors) == 1 and isinstance(errors[0], hal.SourceCorrupt)
    msg = str(errors[0])
    assert str(bad) in msg and "could not be decoded" in msg and "goes on at frame" in msg
    seqs = [f.seq for f in frames]
    lost = sorted(set(range(SQUAT_FRAMES)) - set(seqs))
    assert seqs == sorted(seqs) and lost and f"frames {lost[0]}..{lost[-1]}" in msg
    assert info["corrupt"] == 1
    # frames well before the damage are intact; after it the decoder resumes on the right pictures (smeared,
    # as H.264 frames decoded without their references are); timestamps follow the file's PTS through the gap
    assert all(np.array_equal(f.image, squat_frames[f.seq]) for f in frames if f.seq < lost[0] - 1)
    after = [f for f in frames if f.seq > lost[-1]]

    def smear(shift: int) -> float:  # mean |difference| of the pictures after the gap to clean frame seq + shift
        return float(np.mean([np.abs(f.image.astype(int) - squat_frames[f.seq + shift]).mean() for f in after
                              if 0 <= f.seq + shift < SQUAT_FRAMES]))

    # How smeared a picture is depends on the decoder's error concealment (FFmpeg build, threads), and the first
    # pictures after the gap still show older content, so no fixed bound on the smear is asked. The claim is
    # relative: over the frames after the gap the pictures are closest to the clean frames of their own seq,
    # not to the ones before or after (measured 6.8 vs 8.7-8.9): seq and picture stay aligned.
    assert after and smear(0) < min(smear(-1), smear(1))
    assert all(f.t - frames[0].t == pytest.approx(f.seq / SQUAT_FPS, abs=1e-6) for f in frames)


def test_truncated_mp4_is_corrupt_at_open(tmp_path, squat_video):
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(squat_video.read_bytes()[:250_000])  # loses the moov index at the end of the file
    src = hal.open_source(f"file:{cut}")
    with pytest.raises(hal.SourceCorrupt, match=r"cut\.mp4: OpenCV/FFmpeg cannot open this video.*truncated"):
        src.open()


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(hal.SourceNotFound, match="gone.mp4: no such file"):
        hal.open_source(f"file:{tmp_path / 'gone.mp4'}")
    notes = tmp_path / "notes.txt"
    notes.write_text("not a video")
    with pytest.raises(hal.SourceUnsupported, match="notes.txt: not a video"):
        hal.open_source(f"file:{notes}")
    not_video = tmp_path / "fake.mp4"
    not_video.write_text("not a video either")
    with pytest.raises(hal.SourceCorrupt, match="fake.mp4"):
        hal.open_source(f"file:{not_video}").open()
