"""A real ``posed web`` process for the browser tests: started in a session of its own, its URL read from the
first line it prints."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def posed_web(robot: str, endpoint: str, wait_s: float = 120.0) -> tuple[subprocess.Popen, str]:
    """``posed web ROBOT --connect ENDPOINT`` on a free port: the process and the page's URL."""
    proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "web", robot, "--connect", endpoint, "--port", "0",
                             "--wait", str(wait_s)], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True, start_new_session=True)
    url = proc.stdout.readline().strip()
    assert url.startswith("http://127.0.0.1:"), f"posed web printed {url!r} (exit {proc.poll()})"
    return proc, url


def web_page(robot: str, endpoint: str, procs: list, profile: Path):
    """A real ``posed web ROBOT`` and a headless Chromium on its page (both appended to ``procs``, the conftest
    fixture that stops them): the :class:`tests.viz.browser.Browser`."""
    from tests.viz.browser import Browser

    proc, url = posed_web(robot, endpoint, 60)
    procs.append(proc)
    b = Browser(profile)
    procs.append(b)
    b.open(url)
    return b
