"""The live web view as a stage of the daemon (``web.enabled``, off by default): the page of ``posed web``
served by a process the supervisor starts, watches and restarts like the others.

It is a receiver like any other: it connects to this daemon's own Zenoh endpoints with a session of its own
and shows what the topics carry (poses, status, fall events, the history; never an image), and acknowledges
through the same ack key as every other receiver. It is ready at once, whether or not the page could be served
or the publisher's session is up yet (a port in use is logged and retried every 5 s; the page says "waiting"
until the session is up): a browser view must never hold back, or stop, the pipeline and its fall detection. The address is logged (``web_serving``).
"""

from __future__ import annotations

import threading
import time

from posed.daemon.bus.session import daemon_endpoints
from posed.daemon.stages.base import StageRuntime

CONNECT_TRY_S = 0.5
BIND_RETRY_S = 5.0


def run(rt: StageRuntime) -> None:
    from posed.client import PosedClient, PosedClientError
    from posed.viz.web.bus import RobotLink
    from posed.viz.web.hub import Hub
    from posed.viz.web.server import WebServer

    config = rt.config
    web = config.web
    hub = Hub(config.robot_id, web.pose_rate_hz)
    link = _LateLink()
    rt.ready()      # nothing to warm up; a failing page must not hold back (or stop) fall detection
    server, client, eps = None, None, list(daemon_endpoints(config.zenoh))
    next_bind, warned = 0.0, False
    try:
        while True:
            rt.beat()
            rt.check_stop()
            now = time.monotonic()
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
                except PosedClientError:
                    continue
                link.attach(RobotLink(client, hub, config.robot_id))
                rt.log.info("web_connected", endpoints=eps)
            time.sleep(0.1)
    finally:
        if server is not None:
            server.shutdown()
            server.server_close()
        if client is not None:
            client.close()


class _LateLink:
    """The page's link to the robot, attached once the Zenoh session is up; until then an ack or a history
    request is answered as 'not reachable' instead of blocking the page."""

    def __init__(self) -> None:
        self._link = None

    def attach(self, link) -> None:
        self._link = link

    def ack(self, event_id: str) -> bool:
        return self._link.ack(event_id) if self._link is not None else False

    def history(self) -> list[dict]:
        return self._link.history() if self._link is not None else []
