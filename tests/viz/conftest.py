"""Fixtures of the browser tests: processes and browsers started by a test, stopped after it."""

from __future__ import annotations

import os
import signal

import pytest

from posed.commands._child import stop
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
