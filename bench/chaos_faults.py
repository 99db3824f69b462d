"""Faults of the chaos campaign beyond the stages (bench/chaos.py): idle web connections and a state directory
that goes read-only and then full while the daemon runs (issue 34).

* :class:`IdleWeb`: ``count`` TCP connections to the daemon's web stage that connect and send nothing (a local
  process holding sockets), kept open for a while; meanwhile the page is asked for ``/api/history`` every
  ``probe_every_s`` and each answer's time recorded (a caregiver's browser must still be answered).
* :class:`StorageFaults`: the state directory on a small tmpfs of its own (root only: ``mount``), remounted
  read-only, then writable but full (a filler file takes every free byte), then freed again, at given
  fractions of the chaos. Without root or ``mount`` the fault is reported as not run, never faked.

Times in seconds on the monotonic clock.
"""

from __future__ import annotations

import http.client
import os
import resource
import shutil
import socket
import subprocess
import threading
import time
from pathlib import Path


class IdleWeb:
    """Idle connections to 127.0.0.1:``port`` and probes of the page while they are held."""

    def __init__(self, port: int, count: int, probe_timeout_s: float = 10.0) -> None:
        self.port = port
        self.count = count
        self.probe_timeout_s = probe_timeout_s
        self.socks: list[socket.socket] = []
        self.refused = 0
        self.opened_s: float | None = None       # how long opening them took (a full backlog makes it slow)
        self.probes: list[float | None] = []     # answer time of each probe, None: no answer in time
        self.statuses: list[int] = []

    def open(self) -> None:
        soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
        want = self.count + 256
        if soft < want:
            resource.setrlimit(resource.RLIMIT_NOFILE, (min(want, hard), hard))
        t0 = time.monotonic()
        for _ in range(self.count):
            s = socket.socket()
            s.settimeout(0.2)
            try:
                s.connect(("127.0.0.1", self.port))
            except OSError:
                self.refused += 1
                s.close()
                continue
            self.socks.append(s)
        self.opened_s = round(time.monotonic() - t0, 1)

    def probe(self) -> None:
        t0 = time.monotonic()
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=self.probe_timeout_s)
        try:
            conn.request("GET", "/api/history")
            resp = conn.getresponse()
            resp.read()
            self.statuses.append(resp.status)
            self.probes.append(round(time.monotonic() - t0, 3))
        except (OSError, http.client.HTTPException):
            self.probes.append(None)
        finally:
            conn.close()

    def hold(self, seconds: float, probe_every_s: float = 2.0) -> threading.Thread:
        """Open the connections, probe the page every ``probe_every_s`` for ``seconds``, close them; in a
        thread of its own (a probe may wait ``probe_timeout_s``)."""
        t_end = time.monotonic() + seconds
        opener = threading.Thread(target=self.open, name="chaos-idle-open", daemon=True)

        def run() -> None:
            opener.start()
            try:
                while time.monotonic() < t_end:
                    self.probe()
                    time.sleep(probe_every_s)
            finally:
                opener.join(max(0.0, t_end - time.monotonic()) + 30)
                self.close()
        t = threading.Thread(target=run, name="chaos-idle-web", daemon=True)
        t.start()
        return t

    def close(self) -> None:
        for s in self.socks:
            s.close()
        self.socks.clear()

    def report(self) -> dict:
        answered = [p for p in self.probes if p is not None]
        return {"idle_connections": self.count - self.refused, "refused": self.refused, "opened_s": self.opened_s,
                "probes": len(self.probes), "answered": len(answered),
                "ok_answers": sum(1 for s in self.statuses if s == 200),
                "slowest_answer_s": max(answered) if answered else None}


def can_mount() -> bool:
    return os.geteuid() == 0 and shutil.which("mount") is not None


class StorageFaults:
    """The state directory on a tmpfs of ``size_kb`` that the campaign turns read-only, then full, then back."""

    def __init__(self, state: Path, size_kb: int = 4096) -> None:
        self.state = state
        self.size_kb = size_kb
        self.mounted = False
        self.log: list[tuple[str, float]] = []       # (what, when)
        self.error: str | None = None
        self.read_only_tries = 0

    def mount(self) -> bool:
        self.state.mkdir(parents=True, exist_ok=True)
        if not can_mount():
            self.error = "not root or no mount(8): the state-directory faults were not run"
            return False
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={self.size_kb}k,mode=0700", "tmpfs",
                            str(self.state)], capture_output=True, text=True)
        if r.returncode != 0:
            self.error = f"mount tmpfs failed: {r.stderr.strip()}"
            return False
        self.mounted = True
        return True

    def _remount(self, mode: str) -> str | None:
        r = subprocess.run(["mount", "-o", f"remount,{mode}", str(self.state)], capture_output=True, text=True)
        return None if r.returncode == 0 else r.stderr.strip() or f"mount exited {r.returncode}"

    def read_only(self, release=None, timeout_s: float = 10.0) -> None:
        """Remount read-only. A file system with files open for writing cannot be (EBUSY): then ``release()``
        (the campaign kills the stage that holds the journal; its restart meets a read-only state directory,
        as a daemon restarted on a disk that went read-only does) and try again until ``timeout_s``."""
        t_end = time.monotonic() + timeout_s
        tries = 0
        while True:
            tries += 1
            err = self._remount("ro")
            if err is None:
                self.log.append(("read_only", time.monotonic()))
                self.read_only_tries = tries
                return
            if time.monotonic() > t_end:
                self.error = f"remount read-only failed after {tries} tries: {err}"
                return
            if release is not None:
                release()
            time.sleep(0.05)

    def full(self) -> None:
        """Writable again, every free byte taken by a filler file."""
        err = self._remount("rw")
        if err is not None:
            self.error = f"remount writable failed: {err}"
            return
        filler = self.state / "chaos-filler"
        block = b"\0" * (64 * 1024)
        with open(filler, "wb", buffering=0) as fh:
            try:
                while fh.write(block):
                    pass
            except OSError:             # ENOSPC: full (a last partial block may be written)
                pass
            try:
                while fh.write(block[:512]):
                    pass
            except OSError:
                pass
        self.log.append(("full", time.monotonic()))

    def freed(self) -> None:
        (self.state / "chaos-filler").unlink(missing_ok=True)
        self.log.append(("freed", time.monotonic()))

    def unmount(self, keep: Path) -> None:
        """Copy what the state directory holds to ``keep`` (the journal is read there), then unmount."""
        if not self.mounted:
            return
        keep.mkdir(parents=True, exist_ok=True)
        for p in self.state.iterdir():
            if p.is_file() and p.name != "chaos-filler":
                (keep / p.name).write_bytes(p.read_bytes())
        subprocess.run(["umount", "-l", str(self.state)], capture_output=True)
        self.mounted = False

    def report(self, t0: float) -> dict:
        return {"run": self.mounted or bool(self.log), "error": self.error, "size_kb": self.size_kb,
                "faults": [[what, round(t - t0, 1)] for what, t in self.log], "read_only_tries": self.read_only_tries}
