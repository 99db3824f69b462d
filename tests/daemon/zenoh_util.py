"""Zenoh sessions for tests: free ports on 127.0.0.1, a viewer (client), a router standing in for zenohd.
Multicast scouting is always off."""

from __future__ import annotations

import socket
import time

import zenoh

from posed.client import session_config


def free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def config(mode: str, listen=(), connect=()) -> zenoh.Config:
    return session_config(mode, connect=connect, listen=listen)


def client(endpoint: str, timeout: float = 30.0) -> zenoh.Session:
    """A client session to ``endpoint``, retried until the daemon listens."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return zenoh.open(config("client", connect=[endpoint]))
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def router(endpoint: str) -> zenoh.Session:
    return zenoh.open(config("router", listen=[endpoint]))
