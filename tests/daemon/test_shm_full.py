"""A full /dev/shm: the shared-memory segments reserve their pages when they are created, so a /dev/shm
without room is a start-up problem (exit 78, what was needed and free, the fix), never a SIGBUS of the
capture stage at its first frame and a restart loop.

Nothing here fills the machine's real /dev/shm: the reservation is tried on a tiny tmpfs mounted under the
test's temporary folder, and ``posed run`` is run in a private mount namespace (``unshare -m``) whose
/dev/shm is a tiny tmpfs of its own, seen by no other process. Both need root (skipped otherwise)."""

from __future__ import annotations

import mmap
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from posed.daemon.proc import shm

ROOT = Path(__file__).resolve().parents[2]
SQUAT = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"


_WRITE_EVERY_PAGE = textwrap.dedent("""
    import mmap, os, sys
    from posed.daemon.proc import shm
    path, size, do_reserve = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    os.ftruncate(fd, size)          # what SharedMemory(create=True) does: no page is allocated yet
    if do_reserve:
        try:
            shm.reserve(fd, size, "the test segment", shm_dir=os.path.dirname(path))
        except shm.SharedMemoryFull as exc:
            print(exc.message); print(exc.fix); sys.exit(78)
    m = mmap.mmap(fd, size)
    for off in range(0, size, mmap.PAGESIZE):
        m[off] = 1                  # each first write allocates a tmpfs page
    print("written")
""")


def _write_every_page(path: Path, size: int, reserve: bool) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _WRITE_EVERY_PAGE, str(path), str(size), "1" if reserve else "0"],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)


def test_an_unreserved_segment_on_a_full_tmpfs_dies_of_sigbus(tmpfs):
    """The hazard itself (why reserving is needed): 1 MB of pages written into a 256 kB tmpfs."""
    mnt = tmpfs("256k")
    r = _write_every_page(mnt / "seg", 1 << 20, reserve=False)
    assert r.returncode == -7, (r.returncode, r.stdout, r.stderr)     # SIGBUS, no message


def test_reserving_on_a_full_tmpfs_is_a_clear_error(tmpfs):
    mnt = tmpfs("256k")
    r = _write_every_page(mnt / "seg", 1 << 20, reserve=True)
    assert r.returncode == 78, (r.returncode, r.stdout, r.stderr)
    message, fix = r.stdout.splitlines()[:2]
    assert f"{mnt} has no room for the test segment" in message
    assert "needs 1.0 MB (1048576 bytes)" in message
    assert f"{mnt} has 262 kB free" in message                  # what the tmpfs had left (256 KiB)
    assert "--shm-size" in fix and "/dev/shm" in fix and "pipeline.ring_slots" in fix


def test_a_reserved_segment_that_fits_is_written_whole(tmpfs):
    mnt = tmpfs("2m")
    r = _write_every_page(mnt / "seg", 1 << 20, reserve=True)
    assert r.returncode == 0 and "written" in r.stdout, (r.returncode, r.stdout, r.stderr)
    st = os.statvfs(mnt)
    assert (st.f_blocks - st.f_bfree) * st.f_frsize >= 1 << 20       # the pages are really allocated


def test_the_reservation_is_released_with_the_segment():
    """On the real /dev/shm, a small segment: created, reserved (its pages allocated), unlinked."""
    segment = shm.create("test-reserve", 3 * mmap.PAGESIZE + 5)
    try:
        path = Path("/dev/shm") / segment.name
        assert path.stat().st_blocks * 512 >= 3 * mmap.PAGESIZE + 5
    finally:
        shm.destroy(segment)
    assert not path.exists()


def _private_dev_shm(size: str, args: list[str]) -> list[str]:
    """``args`` run with a tmpfs of ``size`` on /dev/shm in a private mount namespace (nothing else sees it)."""
    if os.geteuid() != 0:
        pytest.skip("a private /dev/shm needs root")
    if shutil.which("unshare") is None:
        pytest.skip("unshare (util-linux) is not installed")
    probe = subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c",
                            "mount -t tmpfs -o size=64k tmpfs /dev/shm"], capture_output=True, text=True)
    if probe.returncode:
        pytest.skip(f"this machine does not let the test mount a private /dev/shm: {probe.stderr.strip()}")
    script = f'mount -t tmpfs -o size={size} tmpfs /dev/shm && exec "$@"'
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", script, "sh", *args]


@pytest.mark.parametrize("size, segment", [("1m", "ring"), ("100k", "control")])
def test_posed_run_with_a_full_dev_shm_exits_78_naming_it(tmp_path, shared_data, size, segment):
    """The real daemon on the real squat video: 1 MB of /dev/shm holds the control segment but not the
    11 MB frame ring (before: the capture stage died of SIGBUS at each start, escalation, exit 70); 100 kB not
    even the control segment (before: the same, or the supervisor itself killed by SIGBUS)."""
    from tests.daemon.zenoh_util import free_port

    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{shared_data / SQUAT}",
           "--set", f"pipeline.state_dir={tmp_path / 'state'}", "--set", "logging.format=json",
           "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]"]
    r = subprocess.run(_private_dev_shm(size, cmd), cwd=ROOT, capture_output=True, text=True, timeout=90)
    assert r.returncode == 78, (r.returncode, r.stderr[-3000:])
    err = r.stderr
    assert f"posed: /dev/shm has no room for the {segment} segment posed-" in err
    assert "of shared memory and /dev/shm has" in err and " free" in err
    assert "fix: free space in /dev/shm" in err and "--shm-size" in err
    assert "nothing was started" in err
    log = r.stdout
    assert '"event": "shared_memory_full"' in log and '"exit_code": 78' in log
    assert "stage_start" not in log and "stage_dead" not in log          # no stage ran, none died
