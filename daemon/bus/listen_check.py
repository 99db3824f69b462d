"""Is a ``zenoh.listen`` port already taken at start? Asked by ``posed run`` before any stage is spawned.

Two daemons on one machine (two cameras, two configs) both listening on the default tcp/127.0.0.1:7447 do not
fail: the second one's publisher cannot open its session, logs ``zenoh_unavailable`` once a minute and runs on
without a bus, its poses, status and fall events heard by nobody. So a port that is still taken after
``WAIT_S`` (a daemon stopped just before may still be closing) is a configuration problem (exit 78) naming
who holds it (the robots whose liveliness token a session to that port sees) and the fix. Two daemons started
at the same moment both find the port free here; the publisher of the one that comes second then stops the daemon
with the same problem (:class:`ListenPortTaken`, daemon.bus.link).
"""

from __future__ import annotations

import dataclasses
import errno
import socket
import time

from posed.daemon.bus.session import ZenohConfigError
from posed.daemon.config.sections import ZenohConfig

WAIT_S = 5.0            # how long a taken port is tried again before it is a problem
ASK_S = 2.0             # how long the holder is asked which robots it carries
_TCP = ("tcp", "tls", "ws")


class ListenPortTaken(ZenohConfigError):
    """A ``zenoh.listen`` port stays taken by another program; the message names it and the fix."""

    fix = "give each posed daemon on a machine its own zenoh.listen port (or stop the other one)"


def _host_port(endpoint: str) -> tuple[str, str, int] | None:
    """(protocol, host, port) of a TCP-based endpoint with a fixed port; None for others (port 0, udp, unix)."""
    proto, _, rest = endpoint.partition("/")
    rest = rest.split("#", 1)[0].split("?", 1)[0]
    host, _, port = rest.rpartition(":")
    if proto not in _TCP or not port.isdigit() or int(port) == 0 or not host:
        return None
    return proto, host.strip("[]"), int(port)


def _taken(host: str, port: int) -> bool:
    """True when binding ``host:port`` (as a listener would, SO_REUSEADDR) fails with EADDRINUSE."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            return exc.errno == errno.EADDRINUSE
    return False


def robots_behind(cfg: ZenohConfig, endpoint: str, ask_s: float = ASK_S) -> list[str]:
    """The robot ids whose daemon is reached through ``endpoint`` (their ``posed/ROBOT/alive`` tokens); [] when
    nothing answers (not Zenoh, or a session that needs other credentials)."""
    import zenoh

    from posed.daemon.bus.session import build_config

    proto, host, port = _host_port(endpoint) or ("tcp", "127.0.0.1", 0)
    if host in ("0.0.0.0", "::"):
        endpoint = f"{proto}/127.0.0.1:{port}"
    client = dataclasses.replace(cfg, mode="client", listen=(), connect=(endpoint,), multicast_scouting=False)
    try:
        with zenoh.open(build_config(client)) as session:
            replies = session.liveliness().get("posed/*/alive", timeout=ask_s)
            return sorted({str(r.ok.key_expr).split("/")[1] for r in replies if r.ok is not None})
    except Exception:
        return []


def taken_listen_problems(cfg: ZenohConfig, wait_s: float = WAIT_S) -> list[str]:
    """One problem per ``zenoh.listen`` endpoint whose port is still taken after ``wait_s``, naming the posed
    robots found behind it and the fix; [] when every port is free."""
    found = [(ep, hp) for ep in cfg.listen if (hp := _host_port(ep)) is not None]
    deadline = time.monotonic() + wait_s
    while True:
        taken = [(ep, hp) for ep, hp in found if _taken(hp[1], hp[2])]
        if not taken or time.monotonic() >= deadline:
            break
        time.sleep(0.25)
    problems = []
    for ep, (proto, host, port) in taken:
        robots = robots_behind(cfg, ep)
        who = (f"the posed daemon of robot {', '.join(robots)}" if robots
               else "another program (another posed daemon, or zenohd)")
        problems.append(
            f"zenoh.listen: {ep} is already in use by {who}; each daemon on a machine needs a port of its own: "
            f"give this one another, e.g. --set zenoh.listen=[{proto}/{host}:{port + 1}], and to have both on one "
            f"bus also --set zenoh.connect=[{proto}/{host}:{port}] (or stop the other one)")
    return problems
