"""Run the real Supervisor with a test plan in a subprocess (tests.daemon.supervise_plan) and follow its
status objects; listen to sd_notify messages like systemd does."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from posed.bench.notify_socket import NotifySocket

ROOT = Path(__file__).resolve().parents[2]


NotifyListener = NotifySocket   # systemd's side of the notify protocol (bench.notify_socket)


class Harness:
    def __init__(self, tmp_path: Path, *overrides: str, fatal: bool = False, publisher: bool = False,
                 env: dict | None = None) -> None:
        self.proc = subprocess.Popen(self.command(tmp_path, overrides, fatal, publisher), cwd=ROOT,
                                     env={**os.environ, **(env or {})}, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)

    def command(self, tmp_path: Path, overrides, fatal: bool, publisher: bool) -> list[str]:
        """The supervisor under test (tests.daemon.supervise_plan) writing its statuses to ``status_file``."""
        self.status_file = tmp_path / "status.jsonl"
        cmd = [sys.executable, "-m", "tests.daemon.supervise_plan", str(self.status_file),
               "--set", "pipeline.status_period_s=0.2"]
        for o in overrides:
            cmd += ["--set", o]
        if fatal:
            cmd.append("--fatal")
        if publisher:
            cmd.append("--publisher")
        return cmd

    def statuses(self) -> list[dict]:
        if not self.status_file.exists():
            return []
        lines = self.status_file.read_text().splitlines()
        return [json.loads(x) for x in lines if x.strip().endswith("}")]

    def latest(self) -> dict | None:
        s = self.statuses()
        return s[-1] if s else None

    def wait_for(self, pred, timeout: float, what: str) -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            s = self.latest()
            if s is not None and pred(s):
                return s
            assert self.proc.poll() is None, f"supervisor died while waiting for {what}: {self.stop()}"
            time.sleep(0.05)
        raise AssertionError(f"timed out after {timeout} s waiting for {what}; last status: {self.latest()}")

    def stop(self, sig=15, timeout: float = 10.0) -> tuple[int, str, str, float]:
        t0 = time.monotonic()
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out, err, time.monotonic() - t0
