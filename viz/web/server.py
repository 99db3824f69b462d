"""The HTTP side of the live view: the page, a Server-Sent Events stream, the event history and the
acknowledge action (standard library ``http.server``, one thread per connection).

Hostile local clients (any process on the robot can connect): at most ``MAX_CONNECTIONS`` connections are
served at once (one more is answered ``503`` and closed at once, never queued), a request must arrive within
``REQUEST_TIMEOUT_S`` and an idle kept-alive connection is closed after as long; a malformed request (a
``Content-Length`` that is not a number, a body nested too deeply) is answered ``400``; every refusal and
every handler failure is counted in ``WebServer.counters`` (the web stage logs them once per stats period),
never printed as a traceback.

Routes: ``GET /`` the page, ``GET /static/NAME`` its files, ``GET /stream`` the events (``text/event-stream``:
first a ``snapshot``, then the hub's messages — among them ``robot``, whether posed is running and heard from,
judged twice a second by this server — a comment every ``KEEPALIVE_S`` so proxies keep it open; a page of every
robot names the robot whose live parts it shows, ``?robot=ID``, and gets the ``cards`` of all),
``GET /api/history`` the robot's stored event messages of the page's window (``events``; ``truncated`` when
the robot sent only its newest ``limit``; what they say was acknowledged, the hub learns — also every
``ACK_SYNC_S`` on its own while an event it holds is open), ``POST /api/ack`` (409 for an event of another
robot, or one not listed) ``{"id": ..., "by": NAME}`` (``by``
optional: who acknowledges, kept in the robot's journal; "posed web" without it).

Who may talk to it: with a token configured every request must carry it (``?token=`` — the page passes its
own on — or ``Authorization: Bearer``), compared in constant time. Without a token the server must be on a
loopback address (the config refuses anything else), and the ``Host`` header must name a loopback host (a
web page elsewhere cannot reach it through DNS rebinding). The acknowledge POST must carry the header
``X-Posed: ack``: a cross-site form cannot set it, and a cross-site script would need a CORS preflight this
server never grants.
"""

from __future__ import annotations

import gzip
import hmac
import json
import queue
import selectors
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from posed.viz.web.bus import AckRefused
from posed.viz.web.fall_list import KEEP_S
from posed.viz.web.hub import Hub

STATIC = Path(__file__).resolve().parent / "static"
TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
         ".css": "text/css; charset=utf-8"}
KEEPALIVE_S = 15.0
JUDGE_EVERY_S = 0.5             # how often the hub judges whether the robot is still heard from
ACK_SYNC_S = 60.0               # while an event held is open, how often the robot's journal is read for acks
SYNC_SPAN_S = 86400.0           # ... one read per day from an open event older than the page's window
LOOPBACK_HOSTS = {"127.0.0.1", "localhost", "::1", "[::1]"}
MAX_BODY = 4096
GZIP_ABOVE = 8192               # JSON answers larger than this go gzipped to a browser that accepts it
MAX_BY_CHARS = 128                  # who acknowledged: daemon.bus.acks.MAX_BY_CHARS
MAX_CONNECTIONS = 64            # browsers open a handful each (the page, its files, the stream)
REQUEST_TIMEOUT_S = 10.0        # to send a request, or between two on a kept-alive connection
_BUSY_BODY = b'{"error": "too many connections to this page; try again in a moment"}\n'
BUSY = (b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nConnection: close\r\n"
        b"Content-Length: " + str(len(_BUSY_BODY)).encode() + b"\r\n\r\n" + _BUSY_BODY)


class WebServer(ThreadingHTTPServer):
    """Serves ``hub`` and acts through ``link`` (a ``viz.web.bus.RobotLink``, or anything with ``ack(id)`` and
    ``history()``). ``port`` 0 picks a free one (``server_address`` tells which)."""

    daemon_threads = True
    request_queue_size = 128

    def __init__(self, hub: Hub, link, host: str = "127.0.0.1", port: int = 8780, token: str = "",
                 max_connections: int = MAX_CONNECTIONS, request_timeout_s: float = REQUEST_TIMEOUT_S) -> None:
        self.hub, self.link, self.token = hub, link, token
        self.stopping = threading.Event()
        self.request_timeout_s = request_timeout_s
        self._slots = threading.BoundedSemaphore(max_connections)
        self._count_lock = threading.Lock()
        self.counters = {"busy": 0, "bad_request": 0, "timeout": 0, "failed": 0, "accept_failed": 0}
        super().__init__((host, port), _Handler)
        self._waiting = _WaitingRoom(self)
        # the robot's verdict is judged against the clock too (a robot that went silent sends nothing)
        threading.Thread(target=self._judge_robot, name="posed-web-robot", daemon=True).start()
        # acknowledgements given elsewhere (another page, posed ack, a phone) reach the hub even with no page open
        threading.Thread(target=self._sync_acks, name="posed-web-acks", daemon=True).start()

    def _judge_robot(self) -> None:
        while not self.stopping.wait(JUDGE_EVERY_S):
            try:
                self.hub.tick()
            except Exception:
                self.count("failed")

    def read_history(self, since: float | None = None, until: float | None = None) -> list[dict]:
        """The robot's stored messages (``link.history()``: the page's window; between ``since`` and ``until``,
        unix s, when given); what they say was acknowledged, the hub learns."""
        events = self.link.history() if since is None else self.link.history(since=since, until=until)
        self.hub.on_history(events)
        return events

    def _sync_acks(self) -> None:
        """While the hub holds events not known to be acknowledged, read the robot's journal for them: the
        page's window, and a day from each older one on (once learned acknowledged, it is dropped)."""
        while not self.stopping.wait(ACK_SYNC_S):
            try:
                self.sync_acks()
            except Exception:       # no bus, no answer: the next round asks again
                self.count("failed")

    def sync_acks(self) -> None:
        window = time.time() - KEEP_S
        since = self.hub.open_since()
        while since is not None and since < window:
            self.read_history(since - 60.0, since + SYNC_SPAN_S)
            since = self.hub.open_since(after=since + SYNC_SPAN_S)
        if since is not None:
            self.read_history()

    def server_close(self) -> None:
        self.stopping.set()
        waiting = getattr(self, "_waiting", None)      # None: the bind failed in __init__
        if waiting is not None:
            waiting.close()
        super().server_close()

    def count(self, what: str, n: int = 1) -> None:
        with self._count_lock:
            self.counters[what] = self.counters.get(what, 0) + n

    def process_request(self, request, client_address) -> None:
        """A new connection waits in the waiting room (no thread) until it sends something."""
        self._waiting.add(request, client_address)

    def dispatch(self, request, client_address) -> None:
        """A connection with a request to read: a thread while a slot is free; otherwise 503 at once."""
        if not self._slots.acquire(blocking=False):
            self.count("busy")
            try:
                request.settimeout(0.5)
                request.sendall(BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except Exception:
            self._slots.release()
            raise

    def process_request_thread(self, request, client_address) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request, client_address) -> None:
        """A handler that raised: counted, never a traceback on stderr (one per hostile request before)."""
        self.count("failed")

    def _handle_request_noblock(self) -> None:
        try:
            super()._handle_request_noblock()
        except OSError:         # accept failed (out of file descriptors): counted, the next poll tries again
            self.count("accept_failed")
            self.stopping.wait(0.05)    # never a busy loop at 100 % of a core

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        host = f"[{host}]" if ":" in host else host
        return f"http://{host}:{port}/" + (f"?token={self.token}" if self.token else "")

    def shutdown(self) -> None:
        self.stopping.set()
        super().shutdown()


class _WaitingRoom:
    """Connections that sent nothing yet, watched by one thread (a selector): an idle connection costs a file
    descriptor, never a thread or a slot. One that becomes readable goes to ``server.dispatch``; one silent
    for ``request_timeout_s`` is closed (counted ``timeout``); beyond ``MAX_WAITING`` the newest is closed at
    once (counted ``busy``)."""

    MAX_WAITING = 4096

    def __init__(self, server: WebServer) -> None:
        self.server = server
        self._sel = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._deadlines: dict[int, float] = {}
        self._closed = False
        threading.Thread(target=self._run, name="posed-web-waiting", daemon=True).start()

    def add(self, request, client_address) -> None:
        with self._lock:
            if self._closed or len(self._deadlines) >= self.MAX_WAITING:
                self.server.count("busy")
                self.server.shutdown_request(request)
                return
            self._sel.register(request, selectors.EVENT_READ, client_address)
            self._deadlines[request.fileno()] = time.monotonic() + self.server.request_timeout_s

    def _run(self) -> None:
        while not self._closed:
            try:
                ready = self._sel.select(timeout=0.2)
            except (OSError, ValueError, KeyError):
                if self._closed:
                    return
                time.sleep(0.05)
                continue
            now = time.monotonic()
            with self._lock:
                if self._closed:
                    return
                go = []
                for key, _ in ready:
                    self._forget(key.fileobj)
                    go.append((key.fileobj, key.data))
                expired = [k for k in self._sel.get_map().values() if self._deadlines.get(k.fd, now) < now]
                for key in expired:
                    self._forget(key.fileobj)
            for key in expired:
                self.server.count("timeout")
                self.server.shutdown_request(key.fileobj)
            for request, address in go:
                self.server.dispatch(request, address)

    def _forget(self, request) -> None:
        self._deadlines.pop(request.fileno(), None)
        self._sel.unregister(request)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            for key in list(self._sel.get_map().values()):
                self._sel.unregister(key.fileobj)
                self.server.shutdown_request(key.fileobj)
            self._deadlines.clear()
        self._sel.close()


class _Handler(BaseHTTPRequestHandler):
    server: WebServer
    protocol_version = "HTTP/1.1"

    def setup(self) -> None:
        self.timeout = self.server.request_timeout_s      # the socket's timeout for every read and write
        super().setup()

    def log_message(self, format, *args) -> None:   # no per-request logs
        pass

    def log_error(self, format, *args) -> None:
        if "timed out" in format:          # http.server's own: no request within the timeout
            self.server.count("timeout")

    def handle_one_request(self) -> None:
        try:
            super().handle_one_request()
        except TimeoutError:                # a write that timed out
            self.server.count("timeout")
            self.close_connection = True
        except (ConnectionResetError, BrokenPipeError):
            self.close_connection = True

    def send_error(self, code, message=None, explain=None) -> None:
        """http.server's own refusals (a malformed request line or header): counted, answered as JSON."""
        self.server.count("bad_request")
        self.close_connection = True
        if self.request_version == "HTTP/0.9":     # an unreadable request line: answer with a status line anyway
            self.request_version = "HTTP/1.0"
        try:
            self._send_json({"error": message or HTTPStatus(code).phrase}, HTTPStatus(code))
        except (OSError, ValueError):
            pass

    def _bad(self, text: str, status: HTTPStatus = HTTPStatus.BAD_REQUEST) -> None:
        self.server.count("bad_request")
        self.close_connection = True
        self._send_json({"error": text}, status)

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
        if len(body) > GZIP_ABOVE and "gzip" in (self.headers.get("Accept-Encoding") or ""):
            body = gzip.compress(body, compresslevel=5)     # a week's history: 322 kB, 31 kB gzipped
            self.send_header("Content-Encoding", "gzip")
            self.send_header("Vary", "Accept-Encoding")
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
                events = self.server.read_history()
                limit = getattr(self.server.link, "history_limit", None)
                self._send_json({"events": events, "window_days": KEEP_S / 86400, "limit": limit,
                                 "truncated": limit is not None and len(events) >= limit})
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
        raw_length = (self.headers.get("Content-Length") or "0").strip()
        if not raw_length.isdigit():
            self._bad(f"Content-Length {raw_length[:20]!r} is not a number")
            return
        length = int(raw_length)
        if not 0 < length <= MAX_BODY:
            self._bad("body must be {\"id\": EVENT_ID}", HTTPStatus.BAD_REQUEST if length <= MAX_BODY
                      else HTTPStatus.REQUEST_ENTITY_TOO_LARGE)
            return
        try:
            body = json.loads(self.rfile.read(length))
            event_id = str(body["id"])
            by = body.get("by")
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
            self._bad("body must be {\"id\": EVENT_ID}")
            return
        if by is not None and (not isinstance(by, str) or len(by.strip()) > MAX_BY_CHARS
                               or not by.strip().isprintable()):
            self._bad(f"by must be text of at most {MAX_BY_CHARS} printable characters")
            return
        by = by.strip() if by else None
        try:
            # who acknowledged (the name the page's user gave), kept in the robot's journal
            ok = self.server.link.ack(event_id, by)
        except AckRefused as exc:
            self._send_json({"error": f"cannot acknowledge: {exc}"}, HTTPStatus.CONFLICT)
            return
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
        # a page of every robot says whose live parts it shows (its address' #robot=): those only
        q = hub.subscribe(parse_qs(urlsplit(self.path).query).get("robot", [None])[0])
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Connection", "close")
        self._headers_common()
        self.end_headers()
        self.close_connection = True
        try:
            self._event(hub.snapshot(q.robot))
            while not self.server.stopping.is_set():
                try:
                    msg = q.get(timeout=KEEPALIVE_S)
                except queue.Empty:
                    self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
                    continue
                self._event(hub.resynced(q) or msg)
        except (BrokenPipeError, ConnectionResetError, TimeoutError):
            pass
        finally:
            hub.unsubscribe(q)

    def _event(self, msg: dict) -> None:
        self.wfile.write(b"data: " + json.dumps(msg, allow_nan=False).encode() + b"\n\n")
        self.wfile.flush()
