"""The HTTP side of the live view: the page, a Server-Sent Events stream, the event history and the
acknowledge action (standard library ``http.server``, one thread per connection).

Routes: ``GET /`` the page, ``GET /static/NAME`` its files, ``GET /stream`` the events (``text/event-stream``:
first a ``snapshot``, then the hub's messages, a comment every ``KEEPALIVE_S`` so proxies keep it open),
``GET /api/history`` the robot's stored event messages, ``POST /api/ack`` ``{"id": ...}``.

Who may talk to it: with a token configured every request must carry it (``?token=`` — the page passes its
own on — or ``Authorization: Bearer``), compared in constant time. Without a token the server must be on a
loopback address (the config refuses anything else), and the ``Host`` header must name a loopback host (a
web page elsewhere cannot reach it through DNS rebinding). The acknowledge POST must carry the header
``X-Posed: ack``: a cross-site form cannot set it, and a cross-site script would need a CORS preflight this
server never grants.
"""

from __future__ import annotations

import hmac
import json
import queue
import threading
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from posed.viz.web.hub import Hub

STATIC = Path(__file__).resolve().parent / "static"
TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
         ".css": "text/css; charset=utf-8"}
KEEPALIVE_S = 15.0
LOOPBACK_HOSTS = {"127.0.0.1", "localhost", "::1", "[::1]"}
MAX_BODY = 4096


class WebServer(ThreadingHTTPServer):
    """Serves ``hub`` and acts through ``link`` (a ``viz.web.bus.RobotLink``, or anything with ``ack(id)`` and
    ``history()``). ``port`` 0 picks a free one (``server_address`` tells which)."""

    daemon_threads = True

    def __init__(self, hub: Hub, link, host: str = "127.0.0.1", port: int = 8780, token: str = "") -> None:
        self.hub, self.link, self.token = hub, link, token
        self.stopping = threading.Event()
        super().__init__((host, port), _Handler)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{port}/" + (f"?token={self.token}" if self.token else "")

    def shutdown(self) -> None:
        self.stopping.set()
        super().shutdown()


class _Handler(BaseHTTPRequestHandler):
    server: WebServer
    protocol_version = "HTTP/1.1"

    def log_message(self, format, *args) -> None:   # no per-request logs
        pass

    # ------------------------------------------------------------------ checks
    def _allowed(self) -> bool:
        token = self.server.token
        if token:
            given = parse_qs(urlsplit(self.path).query).get("token", [""])[0]
            auth = self.headers.get("Authorization", "")
            if auth.startswith("Bearer "):
                given = auth[7:]
            if not hmac.compare_digest(given.encode(), token.encode()):
                self._send_json({"error": "a token is needed: open the address posed web printed"},
                                HTTPStatus.UNAUTHORIZED)
                return False
            return True
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0] if "]" not in (self.headers.get("Host") or "") \
            else (self.headers.get("Host") or "").split("]")[0] + "]"
        if host not in LOOPBACK_HOSTS:
            self._send_json({"error": f"host {host!r} refused: this page is served to this machine only"},
                            HTTPStatus.FORBIDDEN)
            return False
        return True

    def _send_json(self, obj, status: HTTPStatus = HTTPStatus.OK) -> None:
        body = json.dumps(obj).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def _headers_common(self) -> None:
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy",
                         "default-src 'self'; img-src 'none'; media-src 'none'; connect-src 'self'; "
                         "frame-ancestors 'none'")

    # ------------------------------------------------------------------ routes
    def do_GET(self) -> None:
        if not self._allowed():
            return
        path = urlsplit(self.path).path
        if path in ("/", "/index.html"):
            self._static("index.html")
        elif path.startswith("/static/"):
            self._static(path[len("/static/"):])
        elif path == "/stream":
            self._stream()
        elif path == "/api/history":
            try:
                self._send_json({"events": self.server.link.history()})
            except Exception as exc:
                self._send_json({"error": f"the robot's history is not available: {exc}"},
                                HTTPStatus.BAD_GATEWAY)
        else:
            self._send_json({"error": f"no such page {path}"}, HTTPStatus.NOT_FOUND)

    def do_POST(self) -> None:
        if not self._allowed():
            return
        if urlsplit(self.path).path != "/api/ack":
            self._send_json({"error": "no such action"}, HTTPStatus.NOT_FOUND)
            return
        if self.headers.get("X-Posed") != "ack":
            self._send_json({"error": "missing header X-Posed: ack"}, HTTPStatus.FORBIDDEN)
            return
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 < length <= MAX_BODY:
            self._send_json({"error": "body must be {\"id\": EVENT_ID}"}, HTTPStatus.BAD_REQUEST)
            return
        try:
            event_id = str(json.loads(self.rfile.read(length))["id"])
        except (ValueError, KeyError, TypeError):
            self._send_json({"error": "body must be {\"id\": EVENT_ID}"}, HTTPStatus.BAD_REQUEST)
            return
        try:
            ok = self.server.link.ack(event_id)
        except Exception as exc:
            self._send_json({"error": f"cannot acknowledge: {exc}"}, HTTPStatus.BAD_GATEWAY)
            return
        self._send_json({"id": event_id, "confirmed": ok})

    def _static(self, name: str) -> None:
        path = (STATIC / name).resolve()
        if path.parent != STATIC or not path.is_file() or path.suffix not in TYPES:
            self._send_json({"error": f"no such file {name}"}, HTTPStatus.NOT_FOUND)
            return
        body = path.read_bytes()
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", TYPES[path.suffix])
        self.send_header("Content-Length", str(len(body)))
        self._headers_common()
        self.end_headers()
        self.wfile.write(body)

    def _stream(self) -> None:
        hub = self.server.hub
        q = hub.subscribe()
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Connection", "close")
        self._headers_common()
        self.end_headers()
        self.close_connection = True
        try:
            self._event(hub.snapshot())
            while not self.server.stopping.is_set():
                try:
                    msg = q.get(timeout=KEEPALIVE_S)
                except queue.Empty:
                    self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
                    continue
                self._event(msg)
        except (BrokenPipeError, ConnectionResetError, TimeoutError):
            pass
        finally:
            hub.unsubscribe(q)

    def _event(self, msg: dict) -> None:
        self.wfile.write(b"data: " + json.dumps(msg, allow_nan=False).encode() + b"\n\n")
        self.wfile.flush()
