"""A whole daemon (``posed run``) as a child process, for the commands that drive one and watch its output over
Zenoh (``posed demo``, ``posed bench pipeline``)."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
from collections.abc import Iterable


def free_endpoint() -> str:
    """A Zenoh endpoint on a TCP port of 127.0.0.1 that is free now: ``tcp/127.0.0.1:PORT``."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"tcp/127.0.0.1:{port}"


def run_command(settings: Iterable[str], config: str | None = None, source: str | None = None,
                overrides: Iterable[str] = ()) -> list[str]:
    """The ``python -m posed.cli run`` command line: ``--set`` for each of ``settings``, then the user's
    ``--config``, ``--source`` and ``--set`` ``overrides`` (which win over ``settings``)."""
    cmd = [sys.executable, "-m", "posed.cli", "run"]
    for item in settings:
        cmd += ["--set", item]
    if config:
        cmd += ["--config", config]
    if source:
        cmd += ["--source", source]
    for item in overrides:
        cmd += ["--set", item]
    return cmd


def stop(proc: subprocess.Popen, timeout_s: float) -> None:
    """SIGTERM (when still running), wait up to ``timeout_s`` seconds for the clean shutdown, then SIGKILL."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
