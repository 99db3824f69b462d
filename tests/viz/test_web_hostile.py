"""The page survives hostile local clients (issue 34 item 3): 1,000 idle connections leave it answering at once
(an idle connection costs a file descriptor, not a thread); idle ones are closed after the request timeout; a
Content-Length that is not a number and a 2,000-deep JSON body are answered 400 and counted, never a traceback;
beyond the connection bound a request is answered 503 at once. Real sockets on 127.0.0.1."""

from __future__ import annotations

import http.client
import resource
import socket
import threading
import time

import pytest

from posed.viz.web.hub import Hub
from posed.viz.web.server import WebServer


class _Robot:
    """What the page's link answers (the bus side is not under test here)."""

    def __init__(self) -> None:
        self.acks: list[str] = []

    def ack(self, event_id, by=None):
        self.acks.append(event_id)
        return True

    def history(self, since=None, until=None):
        return []


@pytest.fixture
def serve():
    servers = []

    def start(**kw):
        s = WebServer(Hub("r"), _Robot(), "127.0.0.1", 0, **kw)
        threading.Thread(target=s.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
        servers.append(s)
        return s

    yield start
    for s in servers:
        s.shutdown()
        s.server_close()


def _get(port, path="/api/history", timeout=10.0):
    t0 = time.monotonic()
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    conn.request("GET", path)
    r = conn.getresponse()
    r.read()
    conn.close()
    return r.status, time.monotonic() - t0


def _raw(port, data: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(data)
        out = b""
        while True:
            chunk = s.recv(65536)
            if not chunk:
                return out
            out += chunk


def test_a_thousand_idle_connections_do_not_hold_the_page(serve):
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(max(soft, 4096), hard), hard))
    s = serve(request_timeout_s=30.0)
    port = s.server_address[1]
    idle = []
    threads_before = threading.active_count()
    try:
        for _ in range(1000):
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        time.sleep(0.5)
        for _ in range(5):
            status, seconds = _get(port)
            assert status == 200 and seconds < 5.0, (status, seconds)
        assert threading.active_count() < threads_before + 10        # no thread per idle connection
    finally:
        for c in idle:
            c.close()


def test_idle_connections_are_closed_after_the_request_timeout(serve):
    s = serve(request_timeout_s=0.5)
    c = socket.create_connection(("127.0.0.1", s.server_address[1]), timeout=5)
    try:
        assert c.recv(10) == b""                 # the server closed it
    finally:
        c.close()
    assert s.counters["timeout"] >= 1


def test_malformed_requests_get_400_and_are_counted(serve):
    s = serve()
    port = s.server_address[1]
    head = f"POST /api/ack HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Posed: ack\r\n"
    answer = _raw(port, (head + "Content-Length: abc\r\n\r\n").encode())
    assert answer.startswith(b"HTTP/1.1 400") and b"not a number" in answer
    deep = b"[" * 2000 + b"]" * 2000
    answer = _raw(port, (head + f"Content-Length: {len(deep)}\r\n\r\n").encode() + deep)
    assert answer.startswith(b"HTTP/1.1 400")
    answer = _raw(port, b"GARBAGE\r\n\r\n")
    assert answer.startswith(b"HTTP/1.1 400")
    assert s.counters["bad_request"] == 3 and s.counters["failed"] == 0
    assert _get(port)[0] == 200                  # and it keeps serving


def test_beyond_the_connection_bound_a_request_is_answered_503_at_once(serve):
    s = serve(max_connections=2, request_timeout_s=30.0)
    port = s.server_address[1]
    held = []
    try:
        for _ in range(2):                        # two connections that sent half a request hold both slots
            c = socket.create_connection(("127.0.0.1", port), timeout=5)
            c.sendall(b"GET /api/history HTTP/1.1\r\n")
            held.append(c)
        time.sleep(0.5)
        status, seconds = _get(port)
        assert status == 503 and seconds < 3.0
        assert s.counters["busy"] >= 1
    finally:
        for c in held:
            c.close()
    time.sleep(0.5)
    assert _get(port)[0] == 200
