"""Night: a RealSense recording whose colour goes dark while its left infrared stream stays, played through the
real pyrealsense2 playback (no camera here): which image each frame carries, with whose intrinsics, depth and
gravity; the modes; recordings without infrared as before; ``posed record`` of infrared frames; and the live
code path on the real ``rs.pipeline`` fed by the recording (its start with the infrared stream, and without it
when the camera cannot)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pyrealsense2 as rs
import pytest

from posed import hal
from posed.camera_model import Intrinsics
from posed.hal.db3 import Db3Writer
from posed.hal.imu import G_M_S2
from posed.hal.night import DARK_LUMA_ENTER, mean_luma
from posed.hal.realsense import RealSenseSource
from tests.hal.conftest import COLOUR_K, DEPTH_SCALE, SQUAT_FPS, TS0_MS, colour_frames, synthetic_depth

# The left infrared imager: the colour's size, its own lens; raw depth is computed on its grid.
IR_K = Intrinsics(fx=400.0, fy=400.5, cx=179.0, cy=321.0, width=COLOUR_K.width, height=COLOUR_K.height)
# The colour camera turned 5 deg about y from the depth sensor (and 15 mm to its right): gravity differs.
TURN = math.radians(5.0)
ROTATION = (math.cos(TURN), 0.0, -math.sin(TURN), 0.0, 1.0, 0.0, math.sin(TURN), 0.0, math.cos(TURN))
# Mean luma of each colour frame: bright, the hysteresis band (35 stays colour), dark, the band again (35 and
# 38 stay infrared), bright (hal.night: infrared below 30, colour again above 40).
LUMAS = (110, 110, 35, 25, 20, 35, 38, 90, 90)
SPECTRA = ["colour"] * 3 + ["infrared"] * 4 + ["colour"] * 2
DOWN_DEPTH = np.array([0.0, math.cos(math.radians(20)), math.sin(math.radians(20))])  # 20 deg tilt, depth axes


@dataclass(frozen=True)
class NightRecording:
    path: Path
    colour: list[np.ndarray]
    infrared: list[np.ndarray]
    depth: list[np.ndarray]


def dimmed(image: np.ndarray, luma: float) -> np.ndarray:
    return np.clip(image.astype(np.float64) * (luma / mean_luma(image)), 0, 255).round().astype(np.uint8)


def write_night(path: Path, squat_frames, *, on_ir_grid: bool = True, infrared: bool = True,
                colour_luma=LUMAS, ir_k: Intrinsics = IR_K, black_ir: bool = False) -> NightRecording:
    """Colour (the real squat video dimmed to ``colour_luma``), its infrared image (the same frames in grey,
    as the left imager sees them), depth on the infrared grid (``on_ir_grid``, a camera's raw depth) or already
    on the colour grid (posed record's), and an accelerometer reading a 20 deg tilt."""
    frames, pts = colour_frames(squat_frames, 30, len(colour_luma))
    colour = [dimmed(f, y) for f, y in zip(frames, colour_luma, strict=True)]
    ir = [np.zeros((ir_k.height, ir_k.width), np.uint8) if black_ir else
          cv2.resize(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), (ir_k.width, ir_k.height)) for f in frames]
    if on_ir_grid:
        depth = [cv2.resize(synthetic_depth(i), (ir_k.width, ir_k.height), interpolation=cv2.INTER_NEAREST)
                 for i in range(len(frames))]
        geometry = {"depth_intrinsics": ir_k, "depth_to_colour": (ROTATION, (0.015, 0.0, 0.0))}
    else:
        depth = [cv2.resize(synthetic_depth(i), (COLOUR_K.width, COLOUR_K.height), interpolation=cv2.INTER_NEAREST)
                 for i in range(len(frames))]
        geometry = {}
    with Db3Writer(path, COLOUR_K, SQUAT_FPS, depth_scale=DEPTH_SCALE, accel_fps=100, infrared=infrared,
                   infrared_intrinsics=ir_k if infrared else None, **geometry) as w:
        n = 0
        for i, image in enumerate(colour):
            while n * 10.0 <= pts[i]:
                w.write_accel(TS0_MS + n * 10.0, tuple(-G_M_S2 * DOWN_DEPTH))
                n += 1
            w.write(image, depth[i], TS0_MS + pts[i], i, **({"infrared": ir[i]} if infrared else {}))
    return NightRecording(path, colour, ir, depth)


def play(path: Path, query: str = "") -> tuple[list[hal.Frame], list[str], dict]:
    frames, errors = [], []
    with hal.open_source(f"file:{path}?realtime=false{query}") as src:
        while True:
            try:
                frames.append(src.read(2.0))
            except hal.EndOfStream:
                return frames, errors, src.info
            except hal.SourceCorrupt as exc:
                errors.append(str(exc))


@pytest.fixture(scope="module")
def night(tmp_path_factory, squat_frames) -> NightRecording:
    return write_night(tmp_path_factory.mktemp("night") / "night.db3", squat_frames)


def test_dark_colour_switches_to_infrared_and_back_with_hysteresis(night):
    frames, errors, info = play(night.path)
    assert errors == [] and [f.seq for f in frames] == list(range(len(LUMAS)))
    assert [f.spectrum for f in frames] == SPECTRA
    rotation = np.asarray(ROTATION).reshape(3, 3).T       # depth axes -> colour axes (hal.imu.rotation_of)
    for f, colour, ir, depth in zip(frames, night.colour, night.infrared, night.depth, strict=True):
        if f.spectrum == "infrared":
            assert np.array_equal(f.image, cv2.cvtColor(ir, cv2.COLOR_GRAY2BGR))
            assert f.intrinsics == IR_K
            assert f.depth is not None and np.array_equal(f.depth, depth)   # raw: it lies on the infrared grid
            assert f.depth_scale == pytest.approx(DEPTH_SCALE)
            down = DOWN_DEPTH                                  # the infrared imager's axes are the depth sensor's
        else:
            assert np.array_equal(f.image, colour) and f.intrinsics == COLOUR_K
            assert f.depth is not None and not np.array_equal(f.depth, depth)  # aligned to colour
            down = rotation @ DOWN_DEPTH
        if f.gravity is not None:
            assert np.allclose(f.gravity, down, atol=1e-6), (f.seq, f.spectrum)
    assert sum(f.gravity is not None for f in frames) >= len(frames) - 1
    assert info["infrared"] == "standby" and info["spectrum"] == "colour"
    assert info["infrared_frames"] == 4 and info["spectrum_switches"] == 2
    assert info["infrared_intrinsics"] == IR_K.to_json()


def test_infrared_state_while_in_use(night):
    with hal.open_source(f"file:{night.path}?realtime=false") as src:
        seen = [(src.read(2.0).spectrum, src.info["infrared"], src.info["spectrum"]) for _ in range(5)]
    assert seen[2] == ("colour", "standby", "colour") and seen[3] == ("infrared", "in use", "infrared")


def test_depth_not_on_the_infrared_grid_is_left_out(tmp_path, squat_frames):
    rec = write_night(tmp_path / "aligned.db3", squat_frames, on_ir_grid=False)
    frames, errors, info = play(rec.path)
    assert errors == [] and [f.spectrum for f in frames] == SPECTRA
    assert info["depth_alignment"] == "raw"
    for f, depth in zip(frames, rec.depth, strict=True):
        if f.spectrum == "infrared":
            assert f.depth is None and f.depth_scale == 0.0 and f.intrinsics == IR_K
        else:
            assert np.array_equal(f.depth, depth)


def test_off_never_switches_and_always_always_does(night):
    frames, errors, info = play(night.path, "&infrared=off")
    assert errors == [] and [f.spectrum for f in frames] == ["colour"] * len(LUMAS)
    assert all(np.array_equal(f.image, c) for f, c in zip(frames, night.colour, strict=True))
    assert info["infrared"] == "off" and info["infrared_frames"] == 0 and info["infrared_intrinsics"] is None
    frames, errors, info = play(night.path, "&infrared=always")
    assert errors == [] and [f.spectrum for f in frames] == ["infrared"] * len(LUMAS)
    assert all(f.intrinsics == IR_K for f in frames)
    assert info["infrared"] == "in use" and info["infrared_frames"] == len(LUMAS) and info["spectrum_switches"] == 1
    with pytest.raises(hal.SourceUnsupported, match="auto, off, always"):
        hal.open_source(f"file:{night.path}?infrared=night")


def test_a_recording_without_infrared_plays_as_before(tmp_path, squat_db3, squat_frames):
    frames, errors, info = play(squat_db3.path)
    assert errors == [] and all(f.spectrum == "colour" for f in frames)
    assert all(np.array_equal(f.image, c) for f, c in zip(frames, squat_db3.colour, strict=True))
    assert info["infrared"] == "none" and info["infrared_frames"] == 0
    # dark colour without infrared: dim frames go through as they are, black ones are blank, as before
    rec = write_night(tmp_path / "no_ir.db3", squat_frames, infrared=False, colour_luma=(20, 0.5, 20))
    frames, errors, info = play(rec.path)
    assert [f.seq for f in frames] == [0, 2] and all(f.spectrum == "colour" for f in frames)
    assert len(errors) == 1 and "blank frames" in errors[0] and "infrared" not in errors[0]
    assert info["blank"] == 1


def test_a_blank_colour_frame_with_infrared_delivers_the_infrared_one(tmp_path, squat_frames):
    rec = write_night(tmp_path / "covered.db3", squat_frames, colour_luma=(110, 0.5, 110))
    frames, errors, info = play(rec.path)
    assert errors == [] and [f.spectrum for f in frames] == ["colour", "infrared", "colour"]
    assert np.array_equal(frames[1].image, cv2.cvtColor(rec.infrared[1], cv2.COLOR_GRAY2BGR))
    # the infrared image blank too: the blank error, as for colour
    rec = write_night(tmp_path / "both_black.db3", squat_frames, colour_luma=(110, 0.5, 110), black_ir=True)
    frames, errors, info = play(rec.path)
    assert [f.seq for f in frames] == [0, 2] and info["blank"] == 1
    assert len(errors) == 1 and "blank frames" in errors[0] and "its infrared image too" in errors[0]


def test_an_infrared_stream_of_another_size_is_not_used_and_says_why(tmp_path, squat_frames):
    small = Intrinsics(fx=200.0, fy=200.0, cx=89.5, cy=159.5, width=180, height=320)
    rec = write_night(tmp_path / "small.db3", squat_frames, ir_k=small, on_ir_grid=False)
    frames, errors, info = play(rec.path)
    assert errors == [] and all(f.spectrum == "colour" for f in frames) and len(frames) == len(LUMAS)
    assert info["infrared"].startswith("error: the infrared stream is 180x320, the colour one 360x640")


def test_record_keeps_infrared_frames_as_infrared(tmp_path, night):
    out = tmp_path / "again.db3"
    with hal.open_source(f"file:{night.path}?realtime=false") as src:
        summary = hal.record(src, str(out))
    assert summary.frames == len(LUMAS) and summary.has_depth
    assert any("4 frames were infrared images" in n and "infrared stream" in n for n in summary.notes), summary.notes
    before, _, _ = play(night.path)
    after, errors, info = play(out)
    assert errors == [] and [f.spectrum for f in after] == SPECTRA
    for a, b in zip(after, before, strict=True):
        assert np.array_equal(a.image, b.image) and a.intrinsics == b.intrinsics and a.seq == b.seq
        if a.spectrum == "colour":
            assert np.array_equal(a.depth, b.depth)
    # a video keeps one image a frame: the infrared ones as they came, and the notes say so
    video = tmp_path / "again.mkv"
    with hal.open_source(f"file:{night.path}?realtime=false") as src:
        summary = hal.record(src, str(video))
    assert any("4 frames were infrared images" in n and "ordinary frames" in n for n in summary.notes)


class FileCamera(rs.pipeline):
    """The real ``rs.pipeline``, live code path, fed by a recording instead of a camera (none here); the first
    ``failing`` starts fail as a camera that cannot give the streams asked would."""

    path = ""
    failing = 0

    def start(self, cfg):
        if FileCamera.failing > 0:
            FileCamera.failing -= 1
            raise RuntimeError("simulated: Couldn't resolve requests")
        cfg.enable_device_from_file(FileCamera.path, repeat_playback=False)
        return super().start(cfg)


class LiveSource(RealSenseSource):
    def _find_device(self) -> None:       # the "camera" is the recording FileCamera plays
        pass


def live(path: Path, mode: str, failing: int = 0) -> tuple[list[hal.Frame], dict]:
    FileCamera.path, FileCamera.failing = str(path), failing
    cfg = hal.SourceConfig(type="realsense", width=COLOUR_K.width, height=COLOUR_K.height, fps=SQUAT_FPS,
                           imu=False, infrared=mode, read_timeout_s=1.0)
    frames = []
    with LiveSource(cfg, pipeline_factory=FileCamera) as src:
        for _ in range(2 * len(LUMAS)):
            try:
                frames.append(src.read(1.0))
            except hal.SourceTimeout:
                break                     # the file played to its end: a live pipeline just stops sending
        return frames, src.info


def test_live_camera_streams_infrared_and_falls_back_without_it(night):
    frames, info = live(night.path, "auto")
    assert {f.spectrum for f in frames} == {"colour", "infrared"}, [f.spectrum for f in frames]
    for f in frames:   # a live pipeline may drop frames: each is judged by what it shows
        if f.spectrum == "infrared":
            assert f.intrinsics == IR_K and f.depth is not None
            assert np.array_equal(f.image[:, :, 0], f.image[:, :, 2])        # grey
        else:
            assert f.intrinsics == COLOUR_K and mean_luma(f.image) > DARK_LUMA_ENTER
    # a camera that cannot start with the infrared stream starts without it under auto, and says why
    frames, info = live(night.path, "auto", failing=1)
    assert frames and all(f.spectrum == "colour" for f in frames)
    assert info["infrared"] == ("error: the camera cannot start with it (simulated: Couldn't resolve requests); "
                                "streaming colour without it")
    # under always that is the camera's start error, naming the infrared stream
    with pytest.raises(hal.SourceNotFound, match=r"\+ depth \+ infrared \(simulated.*source.infrared auto"):
        live(night.path, "always", failing=1)
