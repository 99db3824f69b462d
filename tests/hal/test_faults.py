"""Fault injection (config keys or URI query) on a real video replay: drop, stall, disconnect, corrupt."""

from __future__ import annotations

import pytest

from posed import hal
from posed.hal.faults import FaultySource


def uri(video, query: str) -> str:
    return f"file:{video}?realtime=false&{query}"


class FakeClock:
    """Scripted time for the fault wrapper: ``sleep`` advances it, nothing else does. The waits of a stall or
    an unplug are then exact, whatever the machine's load (the real clock is the default and is used by
    test_faults_from_config_keys_and_all_at_once)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds >= 0
        self.now += seconds


def scripted(video, query: str, clock: FakeClock) -> FaultySource:
    """The wrapper hal.open_source makes for ``query``, on the scripted clock (the replay is not paced)."""
    plain = hal.open_source(uri(video, query))
    assert isinstance(plain, FaultySource)
    return FaultySource(plain.inner, plain.config, clock=clock, sleep=clock.sleep)


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
    clock = FakeClock()
    with scripted(squat_video, "stall_at=3&stall_s=0.5", clock) as src:
        assert [src.read().seq for _ in range(3)] == [0, 1, 2]
        t0 = clock()
        timeouts = 0
        while True:
            try:
                frame = src.read(0.15)
                break
            except hal.SourceTimeout as exc:
                assert "stall_at=3" in str(exc)
                timeouts += 1
        # three reads wait their whole 0.15 s, the fourth until the stall ends: 0.5 s in all
        assert frame.seq == 3 and timeouts == 3
        assert clock() - t0 == pytest.approx(0.5, abs=1e-9)
        assert src.read().seq == 4
        assert src.info["fault_stalls"] == 1


def test_disconnect_then_back(squat_video):
    clock = FakeClock()
    with scripted(squat_video, "disconnect_at=2&disconnect_s=0.4", clock) as src:
        assert [src.read().seq for _ in range(2)] == [0, 1]
        t0 = clock()
        with pytest.raises(hal.SourceDisconnected, match="unplugged at frame 2"):
            src.read(1.0)
        assert clock() == t0  # the first read after the unplug fails at once, without waiting
        assert src.info["state"] == "disconnected"
        with pytest.raises(hal.SourceDisconnected, match="still unplugged"):
            src.read(0.1)
        assert clock() - t0 == pytest.approx(0.1, abs=1e-9)  # that one waited its timeout
        frame = src.read(1.0)  # waits for the camera to come back, then streams
        assert frame.seq == 3  # frame 2 was lost with the unplug
        assert clock() - t0 == pytest.approx(0.4, abs=1e-9)  # back exactly when the unplug ends


def test_disconnect_for_good(squat_video):
    clock = FakeClock()
    with scripted(squat_video, "disconnect_at=0&disconnect_s=0", clock) as src:
        with pytest.raises(hal.SourceDisconnected):
            src.read(0.05)
        t0 = clock()
        with pytest.raises(hal.SourceDisconnected):
            src.read(0.1)
        assert clock() - t0 == pytest.approx(0.1, abs=1e-9)  # later reads still honour their timeout


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
