"""``posed web [ROBOT]``: the live view in a browser (viz.web), served on 127.0.0.1 by default.

Connects to the robot's daemon over Zenoh (``--connect``, else the config's ``zenoh.connect``, else this
machine's daemon on its ``zenoh.listen`` endpoints), subscribes to its pose, status, events and liveliness,
and serves the page; prints the page's address on stdout. Serving beyond this machine needs ``web.host``
and ``web.token`` in the config (the config check refuses a non-loopback host without a token). Stops on
Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import argparse
import signal
import threading

from posed.commands import add_config_args, config_from_args, error_printer


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("web", help="serve the live view (3D skeleton, angles, status, fall events with "
                                        "acknowledge) on http://127.0.0.1")
    parser.add_argument("robot", nargs="?", metavar="ROBOT",
                        help="robot id (default: the config's robot_id); '*': every robot on the bus, a card each, "
                             "the skeleton of the one chosen")
    parser.add_argument("--connect", action="append", metavar="ENDPOINT",
                        help="Zenoh endpoint of the daemon or router, e.g. tcp/127.0.0.1:7447 (repeatable)")
    parser.add_argument("--port", type=int, metavar="N", help="TCP port (default web.port; 0 = any free one)")
    parser.add_argument("--wait", type=float, default=60.0, metavar="S",
                        help="keep trying to reach the daemon this long at start (default 60 s; a daemon "
                             "starts its Zenoh session after loading the models)")
    add_config_args(parser, source=False, example="web.port=8781")
    parser.set_defaults(func=run)


_err = error_printer("posed web")


def endpoints(config, given: list[str] | None) -> list[str]:
    """Where the daemon is: ``given``, else the config's connect list, else its own listen endpoints (a
    wildcard address as 127.0.0.1)."""
    from posed.daemon.bus.session import daemon_endpoints

    return list(given or config.zenoh.connect or daemon_endpoints(config.zenoh))


def run(args: argparse.Namespace) -> int:
    from posed.client import PosedClient, PosedClientError
    from posed.viz.web.bus import RobotLink
    from posed.viz.web.hub import Hub
    from posed.viz.web.server import WebServer

    config = config_from_args(args)
    web = config.web
    robot = args.robot or config.robot_id
    port = web.port if args.port is None else args.port
    eps = endpoints(config, args.connect)
    hub = Hub(robot, web.pose_rate_hz)
    try:
        client = PosedClient.connect(eps, wait_s=args.wait, config_file=config.zenoh.config_file or None)
    except PosedClientError as exc:
        _err(str(exc))
        return 1
    with client:
        link = RobotLink(client, hub, robot)
        try:
            server = WebServer(hub, link, web.host, port, web.token)
        except OSError as exc:
            _err(f"cannot serve on {web.host}:{port}: {exc.strerror or exc} (another program on that port? "
                 "--port another, or 0 for any free one)")
            return 1

        def stop(*_):
            threading.Thread(target=server.shutdown, daemon=True).start()

        signal.signal(signal.SIGTERM, stop)
        signal.signal(signal.SIGINT, stop)
        print(server.url, flush=True)
        _err(f"robot {robot} over {', '.join(eps)}; open {server.url} (Ctrl-C stops)")
        try:
            server.serve_forever(poll_interval=0.2)
        finally:
            server.server_close()
    return 0
