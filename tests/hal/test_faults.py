"""Fault injection (config keys or URI query) on a real video replay: drop, stall, disconnect, corrupt."""

from __future__ import annotations

import time

import pytest

import hal
from hal.faults import FaultySource


def uri(video, query: str) -> str:
    return f"file:{video}?realtime=false&{query}"


def test_drop_is_seeded_and_leaves_gaps(squat_video):
    runs = []
    for _ in range(2):
        with hal.open_source(uri(squat_video, "drop=0.3&seed=7")) as src:
            seqs = []
            while True:
                try:
                    seqs.append(src.read().seq)
                except hal.EndOfStream:
                    break
            runs.append((seqs, src.info["fault_dropped"]))
    (seqs, dropped), (again, _) = runs
    assert seqs == again  # same seed, same frames
    assert seqs == sorted(seqs) and len(seqs) + dropped == 65
    assert 10 <= dropped <= 30  # ~0.3 x 65


def test_stall_times_out_reads_then_delivers_the_held_frame(squat_video):
    src = hal.open_source(uri(squat_video, "stall_at=3&stall_s=0.5"))
    assert isinstance(src, FaultySource)
    with src:
        assert [src.read().seq for _ in range(3)] == [0, 1, 2]
        t0 = time.monotonic()
        timeouts = 0
        while True:
            try:
                frame = src.read(0.15)
                break
            except hal.SourceTimeout as exc:
                assert "stall_at=3" in str(exc)
                timeouts += 1
        waited = time.monotonic() - t0
        assert frame.seq == 3 and timeouts >= 2
        assert 0.45 <= waited <= 1.0
        assert src.read().seq == 4
        assert src.info["fault_stalls"] == 1


def test_disconnect_then_back(squat_video):
    with hal.open_source(uri(squat_video, "disconnect_at=2&disconnect_s=0.4")) as src:
        assert [src.read().seq for _ in range(2)] == [0, 1]
        t0 = time.monotonic()
        with pytest.raises(hal.SourceDisconnected, match="unplugged at frame 2"):
            src.read(1.0)
        assert time.monotonic() - t0 < 0.1  # the first read after the unplug fails at once
        assert src.info["state"] == "disconnected"
        with pytest.raises(hal.SourceDisconnected, match="still unplugged"):
            src.read(0.1)
        frame = src.read(1.0)  # waits for the camera to come back, then streams
        assert frame.seq == 3  # frame 2 was lost with the unplug
        assert 0.35 <= time.monotonic() - t0 <= 1.0


def test_disconnect_for_good(squat_video):
    with hal.open_source(uri(squat_video, "disconnect_at=0&disconnect_s=0")) as src:
        with pytest.raises(hal.SourceDisconnected):
            src.read(0.05)
        t0 = time.monotonic()
        with pytest.raises(hal.SourceDisconnected):
            src.read(0.1)
        assert 0.09 <= time.monotonic() - t0 <= 0.5  # later reads still honour their timeout


def test_corrupt_frame_then_next(squat_video):
    with hal.open_source(uri(squat_video, "corrupt_at=1")) as src:
        assert src.read().seq == 0
        with pytest.raises(hal.SourceCorrupt, match=r"frame 1 \(seq 1\) is corrupt \(injected fault corrupt_at=1\)"):
            src.read()
        assert src.read().seq == 2


def test_faults_from_config_keys_and_all_at_once(squat_video):
    cfg = hal.SourceConfig(type="file", path=str(squat_video), realtime=False, fault_corrupt_at=10,
                           fault_stall_at=20, fault_stall_s=0.2, fault_disconnect_at=40, fault_disconnect_s=0.2,
                           fault_drop=0.1, fault_seed=3)
    errors: dict[str, int] = {}
    seqs = []
    with hal.open_source(cfg) as src:
        while True:
            try:
                seqs.append(src.read(0.1).seq)
            except hal.EndOfStream:
                break
            except (hal.SourceCorrupt, hal.SourceTimeout, hal.SourceDisconnected) as exc:
                errors[type(exc).__name__] = errors.get(type(exc).__name__, 0) + 1
        info = src.info
    assert errors["SourceCorrupt"] == 1 and errors["SourceTimeout"] >= 1 and errors["SourceDisconnected"] >= 1
    assert info["faults"]["stall_at"] == 20 and info["fault_dropped"] > 0
    assert seqs == sorted(seqs) and len(seqs) + info["fault_dropped"] + 2 == 65  # corrupt + unplugged frame lost
