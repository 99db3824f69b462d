"""A hook that leaves its session (``setsid``, even ``setsid env -i``: no group, no owner tag) does not outlive
a kill -9 of the supervisor (issue 34 item 8: it lived until the next start). The publisher is a child
subreaper: the hook's orphan comes back to it, and it ends it when it stops, as it does when its supervisor is
gone. Also: the adopted processes are reaped (no zombies) and the descendants walk is checked against /proc.
Real supervisor, publisher and hook processes."""

from __future__ import annotations

import os
import signal
import subprocess
import time
import uuid
from pathlib import Path

import pytest

from posed.daemon.proc import orphans
from tests.daemon.redteam_util import publisher_daemon, until


def _with_token(token: str) -> list[int]:
    """The shells whose command line holds ``token`` (not the daemon's processes, whose --set holds it too)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                argv = (d / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if argv[0] == b"/bin/sh" and any(token.encode() in a for a in argv):
                out.append(int(d.name))
    return out


@pytest.fixture
def subreaper():
    import ctypes

    assert orphans.become_subreaper()
    yield
    ctypes.CDLL(None).prctl(orphans.PR_SET_CHILD_SUBREAPER, 0, 0, 0, 0)   # the test process as it was


def test_descendants_and_reaping_of_adopted_processes(subreaper):
    token = uuid.uuid4().hex
    # a child that starts a grandchild in a session of its own and exits at once: the grandchild is adopted
    child = subprocess.Popen(["setsid", "/bin/sh", "-c", f"sleep 30; : {token}"], start_new_session=True)
    child.wait(10)
    def adopted() -> list[int]:
        """The token's shells once every one is our child: the shell's own fork for ``sleep`` carries the
        same command line for the instant before it execs, and is the shell's child, not ours."""
        shells = _with_token(token)
        parents = [orphans._stat(str(p), Path("/proc")) for p in shells]
        return shells if shells and all(s is not None and s[0] == os.getpid() for s in parents) else []

    grand = until(adopted, 5, "the grandchild, adopted by us")
    assert set(grand) <= set(orphans.descendants(os.getpid()))
    orphans.end(grand)
    until(lambda: orphans.reap_adopted(set()) >= 1 or not [p for p in grand if Path(f"/proc/{p}").exists()],
          5, "the adopted process to be reaped")
    assert not [p for p in grand if Path(f"/proc/{p}").exists()]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("prefix", [["setsid"], ["setsid", "env", "-i"]], ids=["setsid", "setsid-env-i"])
def test_a_setsid_hook_child_dies_with_a_kill_9_of_the_supervisor(tmp_path, prefix):
    token = uuid.uuid4().hex
    argv = [*prefix, "/bin/sh", "-c", f"sleep 300; : {token}"]
    hook = "hooks.on_event=[{argv: [" + ", ".join(f'"{a}"' for a in argv) + "], timeout_s: 10}]"
    h, _ = publisher_daemon(tmp_path, hook)
    try:
        until(lambda: _with_token(token), 90, "the hook's setsid child")
        os.kill(h.proc.pid, signal.SIGKILL)                  # the supervisor only
        h.proc.wait(10)
        t0 = time.monotonic()
        until(lambda: not _with_token(token), 20, "the hook's setsid child to end with its publisher")
        ended_in = time.monotonic() - t0
    finally:
        left = _with_token(token)
        orphans.end(left)
        try:
            os.killpg(h.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left and ended_in < 20
