"""The shared-memory frame ring: copies in and out, overwrite detection, attach from a spawned process,
and the resource-tracker rule (a child attaching must not cause the segment to be unlinked)."""

import multiprocessing
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from posed.camera_model import Intrinsics
from posed.daemon.proc import shm
from posed.daemon.proc.ring import FrameRing, FrameTooLarge


def _frame(h, w, value):
    img = np.full((h, w, 3), value, np.uint8)
    img[0, 0] = (1, 2, 3)
    return img


def test_write_read_round_trip_with_depth():
    ring = FrameRing.create(slots=3, capacity_px=64 * 48, with_depth=True)
    try:
        depth = np.arange(48 * 64, dtype=np.uint16).reshape(48, 64)
        ref = ring.write(_frame(48, 64, 7), seq=5, t_capture=12.5, depth=depth, depth_scale=0.001,
                         intrinsics=Intrinsics(600.0, 601.0, 32.0, 24.0, 64, 48), t_origin=13.0)
        assert (ref.width, ref.height, ref.seq, ref.t_capture, ref.has_depth) == (64, 48, 5, 12.5, True)
        assert ref.intrinsics == Intrinsics(600.0, 601.0, 32.0, 24.0, 64, 48) and ref.t_origin == 13.0
        image, d, scale = ring.read(ref)
        assert image.shape == (48, 64, 3) and image[0, 0].tolist() == [1, 2, 3] and image[5, 5, 0] == 7
        assert np.array_equal(d, depth) and scale == 0.001
    finally:
        ring.close()


def test_overwritten_slot_reads_as_none_and_newest_survives():
    ring = FrameRing.create(slots=2, capacity_px=16 * 16, with_depth=False)
    try:
        refs = [ring.write(_frame(16, 16, i), seq=i, t_capture=float(i)) for i in range(3)]
        assert refs[0].slot == refs[2].slot
        assert ring.read(refs[0]) is None            # slot reused by seq 2
        assert ring.read(refs[1])[0][5, 5, 0] == 1
        assert ring.read(refs[2])[0][5, 5, 0] == 2
    finally:
        ring.close()


def test_a_writer_killed_mid_write_does_not_spoil_the_slot():
    ring = FrameRing.create(slots=1, capacity_px=16 * 16, with_depth=False)
    try:
        ref = ring.write(_frame(16, 16, 1), seq=1, t_capture=1.0)
        ring._hdr[0][0] += 1              # what a writer SIGKILLed between its two lock bumps leaves: odd
        assert ring.read(ref) is None     # a half-written frame is never read
        ref = ring.write(_frame(16, 16, 2), seq=2, t_capture=2.0)   # the restarted writer
        assert ring.read(ref)[0][5, 5, 0] == 2
    finally:
        ring.close()


def test_frame_larger_than_slot_names_the_setting():
    ring = FrameRing.create(slots=2, capacity_px=100, with_depth=False)
    try:
        with pytest.raises(FrameTooLarge, match="pipeline.frame_max_pixels"):
            ring.write(_frame(20, 20, 0), 0, 0.0)
    finally:
        ring.close()


def _child_reads(spec, ref, out):
    ring = FrameRing.attach(spec)
    image, _, _ = ring.read(ref)
    out.put(int(image[3, 3, 0]))
    ring.close()


def test_spawned_child_reads_and_leaving_does_not_unlink():
    ctx = multiprocessing.get_context("spawn")
    ring = FrameRing.create(slots=2, capacity_px=32 * 32, with_depth=False)
    path = Path("/dev/shm") / ring.spec.name
    try:
        ref = ring.write(_frame(32, 32, 42), 1, 1.0)
        q = ctx.Queue()
        for _ in range(2):
            p = ctx.Process(target=_child_reads, args=(ring.spec, ref, q))
            p.start()
            assert q.get(timeout=20) == 42
            p.join(10)
            assert p.exitcode == 0
        assert path.exists(), "a child's exit must not unlink the supervisor's segment"
    finally:
        ring.close()
    assert not path.exists()


def test_no_resource_tracker_warning_after_children_attach(tmp_path):
    """A whole parent/child life cycle prints no 'leaked shared_memory' warning and leaves nothing behind."""
    script = tmp_path / "life.py"
    script.write_text(
        "import multiprocessing, numpy as np\n"
        "from daemon.proc.ring import FrameRing\n"
        "def child(spec, ref):\n"
        "    FrameRing.attach(spec).read(ref)\n"
        "if __name__ == '__main__':\n"
        "    ring = FrameRing.create(2, 64, False)\n"
        "    ref = ring.write(np.zeros((8, 8, 3), np.uint8), 0, 0.0)\n"
        "    p = multiprocessing.get_context('spawn').Process(target=child, args=(ring.spec, ref))\n"
        "    p.start(); p.join()\n"
        "    print(ring.spec.name)\n"
        "    ring.close()\n"
    )
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=root,
                          env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"}, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "leaked" not in proc.stderr and "KeyError" not in proc.stderr, proc.stderr
    assert not (Path("/dev/shm") / proc.stdout.strip()).exists()


def test_remove_stale_deletes_segments_of_dead_supervisors(tmp_path):
    dead = tmp_path / "posed-999999999-ring"
    mine = tmp_path / f"posed-{__import__('os').getpid()}-ring"
    other = tmp_path / "someone-else"
    for p in (dead, mine, other):
        p.write_bytes(b"x")
    assert shm.remove_stale(tmp_path) == [dead.name]
    assert mine.exists() and other.exists() and not dead.exists()
