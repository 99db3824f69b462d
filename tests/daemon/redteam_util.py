"""Helpers of the red-team tests: the real supervisor with the publisher plan (tests.daemon.supervise_plan)
whose stdout and stderr go to files (a flood of log lines must not fill a pipe nobody reads), and waiting."""

from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path

from tests.daemon.harness import ROOT, Harness
from tests.daemon.plan_stages import FALL_OVERRIDES
from tests.daemon.zenoh_util import free_port


class FileHarness(Harness):
    """:class:`Harness` with the supervisor's stdout/stderr in ``tmp_path/out.log`` and ``err.log``."""

    def __init__(self, tmp_path: Path, *overrides: str, publisher: bool = True, env: dict | None = None) -> None:
        cmd = self.command(tmp_path, overrides, False, publisher)
        self.out_path, self.err_path = tmp_path / "out.log", tmp_path / "err.log"
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen(cmd, cwd=ROOT, env={**os.environ, **(env or {})}, stdout=out, stderr=err,
                                         text=True, start_new_session=True)     # its own group: kill -9 it whole

    def stop(self, sig=15, timeout: float = 10.0) -> tuple[int, str, str, float]:
        t0 = time.monotonic()
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        self.proc.wait(timeout)
        return self.proc.returncode, self.out_path.read_text(), self.err_path.read_text(), time.monotonic() - t0

    def log_lines(self) -> list[dict]:
        out = []
        for line in self.out_path.read_text(errors="replace").splitlines():
            try:
                out.append(json.loads(line))
            except ValueError:
                out.append({"event": "<not json>", "line": line[:200]})
        return out


def publisher_daemon(tmp_path: Path, *extra: str) -> tuple[FileHarness, str]:
    """The real publisher fed a scripted fall, listening on a free port of 127.0.0.1 (robot ``r7``)."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    h = FileHarness(tmp_path, f"zenoh.listen=[{ep}]", f"pipeline.state_dir={tmp_path / 'state'}", "robot_id=r7",
                    "zenoh.event_republish_s=600", *FALL_OVERRIDES, *extra)
    return h, ep


def until(pred, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")
