"""``posed run | tee`` and then the reader dies (Ctrl-C killed tee): the real supervisor, on a replay, keeps
supervising with a broken log pipe, still stops on SIGTERM or SIGINT, and no stage outlives it."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.daemon.redteam_util import until
from tests.daemon.zenoh_util import free_port

ROOT = Path(__file__).resolve().parents[2]


def _children(pid: int) -> set[int]:
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.add(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_broken_log_pipe_never_stops_the_supervisor(tmp_path, shared_data, sig):
    recording = shared_data / "falls" / "urfd_dev" / "urfd_18_adl.landmarks.jsonl"
    reader = subprocess.Popen(["cat"], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL)
    daemon = subprocess.Popen(
        [sys.executable, "-m", "posed.cli", "run", "--source", f"file:{recording}",
         "--set", "source.loop=true", "--set", f"pipeline.state_dir={tmp_path / 'state'}",
         "--set", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]", "--set", "logging.format=json",
         "--set", "logging.stats_period_s=1", "--set", "pipeline.status_period_s=0.2"],
        cwd=ROOT, stdout=reader.stdin, stderr=reader.stdin, start_new_session=True)
    reader.stdin.close()
    stages: set[int] = set()
    try:
        until(lambda: daemon.poll() is not None or len(_children(daemon.pid)) >= 3, 60, "the stages")
        assert daemon.poll() is None, "the daemon did not start"  # capture, fitting, publisher
        time.sleep(2.0)
        stages = _children(daemon.pid)
        reader.kill()
        reader.wait()
        time.sleep(3.0)                         # every process writes log lines into the broken pipe
        assert daemon.poll() is None, "the supervisor died of a broken log pipe"
        daemon.send_signal(sig)
        daemon.wait(30)
    finally:
        if daemon.poll() is None:
            import os

            os.killpg(daemon.pid, signal.SIGKILL)
            daemon.wait()
            raise AssertionError(f"the supervisor ignored {sig.name} after its log pipe broke")
    assert daemon.returncode == 0
    until(lambda: not any(_alive(p) for p in stages), 10, "every stage to be gone")
