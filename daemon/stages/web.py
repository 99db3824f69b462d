"""The live web view as a stage of the daemon (``web.enabled``, off by default): the page of ``posed web``
served by a process the supervisor starts, watches and restarts like the others.

It is a receiver like any other: it connects to this daemon's own Zenoh endpoints with a session of its own
and shows what the topics carry (poses, status, fall events, the history; never an image), and acknowledges
through the same ack key as every other receiver. It is ready at once, whether or not the page could be served
or the publisher's session is up yet (a port in use is logged and retried every 5 s; the page says "waiting"
until the session is up): a browser view must never hold back, or stop, the pipeline and its fall detection. The address is logged (``web_serving``).

A bus it cannot reach (a TLS bus whose certificates the stage lacks, a wrong endpoint) is never shown as an
empty history: after ``BUS_WARN_S`` without a session the page shows a banner with the reason and the fix,
``/api/history`` answers 502 with them, the status shows the stage's ``bus_connected: false`` and one
``web_cannot_connect`` error line (then one a minute) says why. The server's refusals (busy, timeouts, bad
requests: viz.web.server) are logged as ``web_stats`` once per ``logging.stats_period_s`` when they changed.
"""

from __future__ import annotations

import threading
import time

from posed.daemon.bus.session import daemon_endpoints
from posed.daemon.stages.base import StageRuntime

CONNECT_TRY_S = 0.5
BIND_RETRY_S = 5.0
BUS_WARN_S = 10.0           # without a session this long: the page, the status and the log say so
BUS_LOG_EVERY_S = 60.0
OPEN_FILES = 8192           # the soft limit raised towards this (idle connections cost a descriptor each)


def run(rt: StageRuntime) -> None:
    from posed.client import PosedClient, PosedClientError
    from posed.viz.web.bus import RobotLink
    from posed.viz.web.hub import Hub
    from posed.viz.web.server import WebServer

    config = rt.config
    web = config.web
    _raise_open_files(OPEN_FILES)
    hub = Hub(config.robot_id, web.pose_rate_hz)
    link = _LateLink()
    rt.ready()      # nothing to warm up; a failing page must not hold back (or stop) fall detection
    server, client, eps = None, None, list(daemon_endpoints(config.zenoh))
    next_bind, warned = 0.0, False
    t_start = time.monotonic()
    next_bus_log, next_stats, last_counters = 0.0, t_start + config.logging.stats_period_s, None
    try:
        while True:
            rt.beat()
            rt.check_stop()
            now = time.monotonic()
            if server is not None and now >= next_stats:
                next_stats = now + config.logging.stats_period_s
                counters = dict(server.counters)
                if counters != last_counters and any(counters.values()):
                    rt.log.info("web_stats", **counters)
                last_counters = counters
            if server is None and now >= next_bind:
                try:
                    server = WebServer(hub, link, web.host, web.port, web.token)
                except OSError as exc:
                    next_bind = now + BIND_RETRY_S
                    if not warned:
                        warned = True
                        rt.log.error("web_cannot_serve", host=web.host, port=web.port,
                                     error=exc.strerror or str(exc), retry_s=BIND_RETRY_S,
                                     fix="another program uses that port: set web.port to a free one, or "
                                         "web.enabled: false; the pipeline runs on without the page")
                    continue
                threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2}, name="posed-web",
                                 daemon=True).start()
                rt.log.info("web_serving", url=server.url)
            if client is None:
                try:
                    client = PosedClient.connect(eps, wait_s=CONNECT_TRY_S,
                                                 config_file=config.zenoh.config_file or None)
                except PosedClientError as exc:
                    link.reason = " ".join(str(exc).split())
                    if now - t_start >= BUS_WARN_S:
                        rt.row.set("bus_down", 1.0)
                        hub.on_bus(False, link.reason, BUS_FIX)
                        if now >= next_bus_log:
                            next_bus_log = now + BUS_LOG_EVERY_S
                            rt.log.error("web_cannot_connect", endpoints=eps, error=link.reason, fix=BUS_FIX,
                                         waiting_s=round(now - t_start, 1))
                    continue
                link.attach(RobotLink(client, hub, config.robot_id))
                rt.row.set("bus_down", 0.0)
                hub.on_bus(True, None, None)
                rt.log.info("web_connected", endpoints=eps)
            time.sleep(0.1)
    finally:
        if server is not None:
            server.shutdown()
            server.server_close()
        if client is not None:
            client.close()


BUS_FIX = ("the web stage joins this daemon's own Zenoh endpoints (zenoh.listen) as a client with "
           "zenoh.config_file; on a TLS bus (deploy/zenoh/) that file must give it a certificate the daemon's ACL "
           "admits, or run `posed web` beside the daemon with a receiver's config (deploy/zenoh/receiver.json5)")


class _LateLink:
    """The page's link to the robot, attached once the Zenoh session is up; until then an ack or a history
    request is refused with the reason (the server answers 502), never answered as an empty history."""

    def __init__(self) -> None:
        self._link = None
        self.reason = "connecting to the robot's bus"

    def attach(self, link) -> None:
        self._link = link

    @property
    def history_limit(self) -> int | None:
        """The attached link's cap on a history answer (the page says when the robot's answer was cut)."""
        return getattr(self._link, "history_limit", None)

    def ack(self, event_id: str, by: str | None = None) -> bool:
        """``by``: who acknowledged, as the page's user typed it (kept in the robot's journal)."""
        return self._attached().ack(event_id, by)

    def history(self, since: float | None = None, until: float | None = None) -> list[dict]:
        return self._attached().history(since=since, until=until)

    def _attached(self):
        if self._link is None:
            raise ConnectionError(f"not connected to the robot's bus: {self.reason}")
        return self._link


def _raise_open_files(want: int) -> None:
    import resource

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    target = want if hard == resource.RLIM_INFINITY else min(want, hard)
    if soft != resource.RLIM_INFINITY and soft < target:
        resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
