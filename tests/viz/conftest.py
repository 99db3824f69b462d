"""Fixtures of the browser tests: processes and browsers started by a test, stopped after it."""

from __future__ import annotations

import os
import signal
import threading

import pytest

from posed.commands._child import stop
from posed.viz.web.server import WebServer
from tests.viz.browser import Browser


@pytest.fixture
def procs():
    """A list to append started processes (their own session) and :class:`Browser` objects to; after the test,
    newest first, each browser is closed and each process still running gets SIGTERM to its group."""
    started: list = []
    yield started
    for p in reversed(started):
        if isinstance(p, Browser):
            p.close()
        elif p.poll() is None:
            try:
                os.killpg(p.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            stop(p, 10.0)


@pytest.fixture
def bus():
    """A Zenoh router on 127.0.0.1 and a list for the test's robots (tests.viz.paused_robot.on_bus)."""
    from tests.viz.paused_robot import on_bus

    with on_bus() as b:
        yield b


@pytest.fixture
def served_page(tmp_path):
    """``open(hub, link, ready)``: a real WebServer of ``hub`` and ``link`` on a free port and a headless Chromium
    page on it, once the JavaScript ``ready`` is true; after the test each page is closed and each server shut."""
    opened = []

    def open_page(hub, link, ready: str):
        server = WebServer(hub, link, "127.0.0.1", 0)
        threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        browser = Browser(tmp_path / f"profile{len(opened)}")
        opened.append((server, browser))
        browser.open(server.url)
        browser.wait_for(ready, 30, "the page and its first message")
        return browser

    yield open_page
    for server, browser in opened:
        browser.close()
        server.shutdown()
        server.server_close()
