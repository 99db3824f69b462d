"""The RealSense source on real pyrealsense2 playback of a .db3 made from the squat video (no camera here):
alignment, intrinsics, deprojection, timestamps, de-duplication, pacing, looping, stalls and recovery."""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyrealsense2 as rs
import pytest

from posed import hal
from posed.hal.config import SourceConfig
from posed.hal.realsense import PLAYBACK_SLICE_S, RESET_SETTLE_S, RealSenseSource
from posed.hal.rs_playback import PlaybackPipeline
from tests.hal.conftest import (
    BOX_MM,
    COLOUR_K,
    DB3_FRAMES,
    DEPTH_K,
    DEPTH_SCALE,
    DEPTH_TO_COLOUR_T,
    SQUAT_FPS,
    WALL_MM,
    box_rect,
)

FAST = SourceConfig(realtime=False, read_timeout_s=2.0)


def read_all(src: hal.Source, timeout: float = 2.0) -> list[hal.Frame]:
    frames = []
    while True:
        try:
            frames.append(src.read(timeout))
        except hal.EndOfStream:
            return frames


def colour_edge(u_depth_edge: float, z_m: float, axis: int) -> float:
    """Colour-image coordinate of a depth-image coordinate at depth z (pinhole, depth->colour translation)."""
    if axis == 0:
        x = (u_depth_edge - DEPTH_K.cx) / DEPTH_K.fx * z_m + DEPTH_TO_COLOUR_T[0]
        return COLOUR_K.fx * x / z_m + COLOUR_K.cx
    y = (u_depth_edge - DEPTH_K.cy) / DEPTH_K.fy * z_m + DEPTH_TO_COLOUR_T[1]
    return COLOUR_K.fy * y / z_m + COLOUR_K.cy


def test_playback_frames_colour_intrinsics_and_timestamps(squat_db3):
    src = hal.open_source(f"file:{squat_db3.path}?realtime=false")
    assert isinstance(src, RealSenseSource)
    with src:
        before = time.monotonic()
        frames = read_all(src)
        after = time.monotonic()
        info = src.info
    assert [f.seq for f in frames] == list(range(DB3_FRAMES))  # repeated framesets removed, none lost
    for f, expected in zip(frames, squat_db3.colour, strict=True):
        assert f.image.shape == (COLOUR_K.height, COLOUR_K.width, 3) and f.image.dtype == np.uint8
        assert np.array_equal(f.image, expected)  # bgr8 is stored losslessly
        assert f.intrinsics == COLOUR_K
        assert f.depth_scale == pytest.approx(DEPTH_SCALE)
    # t = start of replay + recorded time since the first frame (device stamps began at 1000 ms)
    assert before <= frames[0].t <= after
    steps = np.diff([f.t for f in frames])
    assert np.allclose(steps, 1.0 / SQUAT_FPS, atol=1e-6)
    assert info["serial"] == "000000000042" and info["device"] == "squat test"
    assert info["has_depth"] and info["depth_alignment"] == "align"
    assert info["duplicates"] == 0  # every frame came once: nothing repeated, nothing to drop
    assert info["frames"] == DB3_FRAMES and info["state"] == "ended"


def test_depth_is_aligned_to_colour_with_the_extrinsics(squat_db3):
    with hal.open_source(f"file:{squat_db3.path}?realtime=false") as src:
        frames = read_all(src)
    z_box = BOX_MM * DEPTH_SCALE
    for i, f in enumerate(frames):
        assert f.depth is not None and f.depth.shape == f.image.shape[:2] and f.depth.dtype == np.uint16
        v0, v1, u0, u1 = box_rect(i)
        left, right = colour_edge(u0 - 0.5, z_box, 0), colour_edge(u1 - 0.5, z_box, 0)
        top, bottom = colour_edge(v0 - 0.5, z_box, 1), colour_edge(v1 - 0.5, z_box, 1)
        vv, uu = np.mgrid[0:COLOUR_K.height, 0:COLOUR_K.width]
        inside = (uu > left + 1.5) & (uu < right - 1.5) & (vv > top + 1.5) & (vv < bottom - 1.5)
        assert np.all(f.depth[inside] == BOX_MM)
        far = (uu < left - 4) | (uu > right + 4) | (vv < top - 4) | (vv > bottom + 4)
        in_view = (uu > 8) & (uu < COLOUR_K.width - 8) & (vv > 8) & (vv < COLOUR_K.height - 8)
        assert np.all(f.depth[far & in_view] == WALL_MM)
        # the box lands where the 15 mm baseline puts it: 4.2 px right of a plain resize at 1.5 m. Alignment
        # snaps the projected box edges to whole colour pixels (librealsense rounds each depth pixel's
        # corners: up to 0.5 px per edge, a tie decided by float32 rounding, measured exactly 0.5 here); any
        # snapping of the two edges (round, floor or ceil) keeps their mean within 1 px, and 4.2 - 1 > 3
        # still separates it from the plain resize below
        ys, xs = np.nonzero(f.depth == BOX_MM)
        assert xs.mean() == pytest.approx((left + right) / 2, abs=1.0)
        assert ys.mean() == pytest.approx((top + bottom) / 2, abs=1.0)
        plain_resize_centre = COLOUR_K.fx / DEPTH_K.fx * ((u0 + u1 - 1) / 2 - DEPTH_K.cx) + COLOUR_K.cx
        assert abs(xs.mean() - plain_resize_centre) > 3.0


def test_slow_reader_gets_every_frame_once_with_its_own_depth(squat_db3):
    """A reader slower than the playback (it waits before its first read and between reads) still gets every
    frame, once, each colour frame with the depth recorded with it: non-real-time playback waits for it."""
    frames = []
    with hal.open_source(f"file:{squat_db3.path}?realtime=false") as src:
        time.sleep(0.5)  # the playback could run through the whole file meanwhile
        while True:
            try:
                frames.append(src.read(2.0))
            except hal.EndOfStream:
                break
            time.sleep(0.15)
        info = src.info
    assert [f.seq for f in frames] == list(range(DB3_FRAMES))
    assert info["duplicates"] == 0
    z_box = BOX_MM * DEPTH_SCALE
    for i, (f, expected) in enumerate(zip(frames, squat_db3.colour, strict=True)):
        assert np.array_equal(f.image, expected)
        v0, v1, u0, u1 = box_rect(i)  # the box moves 4 depth px (8 colour px) per frame: another frame's
        centre = (colour_edge(u0 - 0.5, z_box, 0) + colour_edge(u1 - 0.5, z_box, 0)) / 2  # depth is off by 8
        assert np.nonzero(f.depth == BOX_MM)[1].mean() == pytest.approx(centre, abs=1.0)


def test_deprojection_matches_librealsense_and_the_scene(squat_db3):
    with hal.open_source(f"file:{squat_db3.path}?realtime=false") as src:
        f = src.read()
    v0, v1, u0, u1 = box_rect(0)
    ud, vd, z = (u0 + u1 - 1) / 2.0, (v0 + v1 - 1) / 2.0, BOX_MM * DEPTH_SCALE
    truth = np.array([(ud - DEPTH_K.cx) / DEPTH_K.fx * z + DEPTH_TO_COLOUR_T[0],
                      (vd - DEPTH_K.cy) / DEPTH_K.fy * z + DEPTH_TO_COLOUR_T[1], z])  # box centre, colour frame
    uc, vc = f.intrinsics.project(truth)
    z_measured = float(f.depth_m()[round(vc), round(uc)])
    assert z_measured == pytest.approx(z, abs=1e-6)
    k = rs.intrinsics()
    k.width, k.height, k.fx, k.fy, k.ppx, k.ppy = (COLOUR_K.width, COLOUR_K.height, COLOUR_K.fx, COLOUR_K.fy,
                                                   COLOUR_K.cx, COLOUR_K.cy)
    k.model, k.coeffs = rs.distortion.none, [0.0] * 5
    ours = f.intrinsics.deproject(uc, vc, z_measured)
    theirs = rs.rs2_deproject_pixel_to_point(k, [float(uc), float(vc)], z_measured)
    assert np.allclose(ours, theirs, atol=1e-6)
    assert np.allclose(ours, truth, atol=1e-6)


def test_realtime_pacing_follows_recorded_timestamps(squat_db3):
    waits = []

    def sleep(seconds: float) -> None:  # the real sleep, recording what the source asked for
        waits.append(seconds)
        time.sleep(seconds)

    src = RealSenseSource(SourceConfig(type="file", path=str(squat_db3.path)), playback=str(squat_db3.path),
                          sleep=sleep)  # realtime is the default
    with src:
        t0 = time.monotonic()
        frames = [src.read(1.0) for _ in range(4)]
        elapsed = time.monotonic() - t0
        late = [time.monotonic() - f.t for f in frames]
    assert elapsed >= 0.6 - 1e-3  # frames at 0, 0.2, 0.4, 0.6 s: the last one is held back
    assert all(d >= -1e-3 for d in late)  # never handed out before its capture time
    # and only until then: each wait ends at the frame's time, so it is at most one frame period and all of
    # them add up to at most the 0.6 s span (however late a loaded machine wakes the reader up)
    assert all(w <= 1 / SQUAT_FPS + 1e-6 for w in waits) and sum(waits) <= 3 / SQUAT_FPS + 1e-6


def test_loop_continues_time_and_seq(squat_db3):
    cfg = SourceConfig(type="file", path=str(squat_db3.path), realtime=False, loop=True)
    with hal.open_source(cfg) as src:
        frames = [src.read(2.0) for _ in range(2 * DB3_FRAMES + 1)]
        assert src.info["passes"] == 2
    assert [f.seq for f in frames] == list(range(2 * DB3_FRAMES + 1))
    t = np.array([f.t for f in frames])
    assert np.allclose(np.diff(t), 1.0 / SQUAT_FPS, atol=1e-6)
    assert np.array_equal(frames[DB3_FRAMES].image, frames[0].image)


class StallingPipeline(PlaybackPipeline):
    """The real playback, with a scripted stall (nothing arrives) after some distinct frames: a USB hiccup."""

    plan: dict = {}

    def start(self, *args, **kwargs):
        if self.plan.get("failing_starts", 0) > 0 and self.plan["started"] >= 1:
            self.plan["failing_starts"] -= 1
            raise RuntimeError("simulated: No device connected")
        self.plan["started"] += 1
        return super().start(*args, **kwargs)

    def try_wait_for_frames(self, timeout_ms=5000):
        p = self.plan
        if p["delivered"] >= p["stall_after"] and p["stall_left"] > 0:
            p["stall_left"] -= 1
            time.sleep(timeout_ms / 1000.0)
            return False, None
        ok, frames = super().try_wait_for_frames(timeout_ms)
        if ok:
            p["numbers"].add(frames.get_color_frame().get_frame_number())
            p["delivered"] = len(p["numbers"])
        return ok, frames


def _stalling_source(path: Path, failing_starts: int) -> RealSenseSource:
    StallingPipeline.plan = {"delivered": 0, "stall_after": 3, "stall_left": 10**6, "started": 0,
                             "failing_starts": failing_starts, "numbers": set()}
    cfg = SourceConfig(realtime=False, timeouts_before_reopen=2, failures_before_reset=2, reconnect_initial_s=0.01,
                       reconnect_max_s=0.05)

    def factory(rs_module):
        if StallingPipeline.plan["started"] >= 1:
            StallingPipeline.plan["stall_left"] = 0  # the re-opened pipeline streams again
        return StallingPipeline(rs_module)

    return RealSenseSource(cfg, playback=str(path), pipeline_factory=factory)


def _drain(src: RealSenseSource, timeout: float) -> tuple[list[hal.Frame], list[str]]:
    frames, errors = [], []
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            frames.append(src.read(timeout))
        except hal.EndOfStream:
            break
        except (hal.SourceTimeout, hal.SourceDisconnected) as exc:
            errors.append(type(exc).__name__)
    return frames, errors


def test_stall_counts_timeouts_then_reopens_and_resumes(squat_db3):
    src = _stalling_source(squat_db3.path, failing_starts=0)
    with src:
        t0 = time.monotonic()
        frames, errors = _drain(src, timeout=0.2)
        info = src.info
    assert errors == ["SourceTimeout", "SourceTimeout"]
    assert info["timeouts"] == 2 and info["reopens"] == 1 and info["hardware_resets"] == 0
    assert [f.seq for f in frames] == list(range(DB3_FRAMES))  # resumed after the last frame, no repeats
    assert np.all(np.diff([f.t for f in frames]) > 0)
    # two 0.2 s timeouts and a restart of the playback pipeline (~1 s in all); a recovery by way of a hardware
    # reset would wait RESET_SETTLE_S (5 s) more before its next start
    assert time.monotonic() - t0 < 2 * 0.2 + RESET_SETTLE_S


def test_failed_reopens_escalate_to_hardware_reset(squat_db3):
    src = _stalling_source(squat_db3.path, failing_starts=2)
    with src:
        frames, errors = _drain(src, timeout=0.2)
        info = src.info
    assert errors[:2] == ["SourceTimeout", "SourceTimeout"]
    assert errors.count("SourceDisconnected") >= 2 and set(errors[2:]) == {"SourceDisconnected"}
    assert info["reopen_failures"] == 2 and info["hardware_resets"] == 1 and info["reopens"] == 1
    assert [f.seq for f in frames] == list(range(DB3_FRAMES))


def test_read_timeout_is_bounded_during_a_stall(squat_db3):
    src = _stalling_source(squat_db3.path, failing_starts=0)
    with src:
        for _ in range(3):
            src.read(1.0)
        t0 = time.monotonic()
        with pytest.raises(hal.SourceTimeout, match="no frame within 0.30 s"):
            src.read(0.3)
        # the read waits its timeout (it asks librealsense in slices of PLAYBACK_SLICE_S) and no longer:
        # the stalled pipeline never delivers, so a wait that ignored the timeout would last librealsense's
        # default 5 s or more. Bound: the timeout, one slice, 1 s of scheduling slack.
        assert 0.3 <= time.monotonic() - t0 <= 0.3 + PLAYBACK_SLICE_S + 1.0


def test_no_camera_is_a_clear_error():
    if len(rs.context().query_devices()) > 0:
        pytest.fail("a RealSense camera is plugged in: this test needs a machine without one")
    with pytest.raises(hal.SourceNotFound, match="no RealSense camera found.*rs-enumerate-devices"):
        hal.open_source("realsense:").open()
    with pytest.raises(hal.SourceNotFound, match="no RealSense camera found"):
        hal.open_source("realsense:123456789").open()


def test_missing_pyrealsense2_is_unsupported_with_advice(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    with pytest.raises(hal.SourceUnsupported, match="pip install pyrealsense2.*libusb"):
        hal.open_source("realsense:").open()


def test_daemon_side_runs_without_pyrealsense2(squat_video):
    code = (
        "import sys; sys.modules['pyrealsense2'] = None\n"
        "import hal\n"
        f"with hal.open_source('file:{squat_video}?realtime=false') as s:\n"
        "    f = s.read()\n"
        "try:\n"
        "    hal.open_source('realsense:').open()\n"
        "except hal.SourceUnsupported as e:\n"
        "    print('unsupported', 'pyrealsense2' in str(e))\n"
        "print(f.image.shape, [m for m in sys.modules if m.startswith('posed.hal.realsense') or m == 'posed.hal.db3'])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         cwd=Path(__file__).resolve().parents[2])
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["unsupported True", "(1280, 720, 3) ['posed.hal.realsense']"]


def test_corrupt_and_missing_recordings(tmp_path, squat_db3):
    cut = tmp_path / "cut.db3"
    cut.write_bytes(squat_db3.path.read_bytes()[: squat_db3.path.stat().st_size // 3])
    with pytest.raises(hal.SourceCorrupt, match="cut.db3: librealsense cannot play this recording"):
        hal.open_source(f"file:{cut}").open()
    bag = tmp_path / "old.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n" + bytes(64))
    with pytest.raises(hal.SourceCorrupt, match="old.bag"):
        hal.open_source(f"file:{bag}").open()
    with pytest.raises(hal.SourceNotFound, match="no such file"):
        hal.open_source(f"file:{tmp_path / 'gone.db3'}")


def test_copy_of_recording_plays_the_same(tmp_path, squat_db3):
    copy = tmp_path / "copy.db3"
    shutil.copy(squat_db3.path, copy)
    with hal.open_source(f"file:{copy}?realtime=false&depth=false") as src:
        frames = read_all(src)
        assert src.info["has_depth"] is False
    assert len(frames) == DB3_FRAMES and all(f.depth is None and f.depth_scale == 0.0 for f in frames)
