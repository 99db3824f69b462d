"""Opening the Zenoh session from the ``zenoh`` config section (tech-notes section a).

The native config file (``zenoh.config_file``, JSON5: TLS, user/password, access control) is read first;
``mode``, ``listen``, ``connect`` and multicast scouting from posed's config are then set over it. The
default is a peer listening on tcp/127.0.0.1:7447, connecting nowhere, without multicast scouting: nothing
leaves the machine unless configured. Call only after spawn, in the process that uses the session, and use
the session as a context manager.
"""

from __future__ import annotations

import json
from pathlib import Path

from posed.daemon.config.sections import ZenohConfig

_ANY_HOST = ("0.0.0.0", "[::]", "::")


def daemon_endpoints(cfg: ZenohConfig) -> tuple[str, ...]:
    """Where a receiver on this machine finds the daemon of ``cfg``: its listen endpoints (a wildcard host as
    127.0.0.1), else the routers it connects to."""
    out = []
    for ep in cfg.listen:
        proto, _, rest = ep.partition("/")
        host, _, port = rest.rpartition(":")
        out.append(f"{proto}/127.0.0.1:{port}" if host in _ANY_HOST else ep)
    return tuple(out) or tuple(cfg.connect)


class ZenohConfigError(ValueError):
    """The native Zenoh config file cannot be used."""


def build_config(cfg: ZenohConfig, listen: tuple[str, ...] | None = None,
                 connect: tuple[str, ...] | None = None, mode: str | None = None):
    """A ``zenoh.Config`` for ``cfg`` (``listen``/``connect``/``mode`` override it, e.g. for a viewer)."""
    import zenoh

    if cfg.config_file:
        path = Path(cfg.config_file)
        if not path.is_file():
            raise ZenohConfigError(f"zenoh.config_file: {path} does not exist; give the path of a Zenoh JSON5 "
                                   "config or leave it empty")
        try:
            zc = zenoh.Config.from_file(str(path))
        except Exception as exc:  # zenoh raises ZError for syntax and schema problems
            raise ZenohConfigError(f"zenoh.config_file: {path} is not a valid Zenoh config: {exc}") from exc
    else:
        zc = zenoh.Config()
    zc.insert_json5("mode", json.dumps(mode or cfg.mode))
    zc.insert_json5("listen/endpoints", json.dumps(list(cfg.listen if listen is None else listen)))
    zc.insert_json5("connect/endpoints", json.dumps(list(cfg.connect if connect is None else connect)))
    zc.insert_json5("scouting/multicast/enabled", json.dumps(bool(cfg.multicast_scouting)))
    return zc


def open_session(cfg: ZenohConfig, **overrides):
    """Open a session; raises ``ZenohConfigError`` or zenoh's ``ZError`` with the reason."""
    import zenoh

    return zenoh.open(build_config(cfg, **overrides))


def describe_open_error(cfg: ZenohConfig, exc: Exception) -> str:
    """One line saying why the session did not open and what to change."""
    text = str(exc)
    if "Address already in use" in text:
        return (f"cannot listen on {', '.join(cfg.listen)}: the address is in use (another posed or zenohd?); "
                "stop it or change zenoh.listen")
    if "Unable to connect" in text:
        return (f"cannot reach {', '.join(cfg.connect)} ({cfg.mode} mode needs it); retrying — start the "
                "router or fix zenoh.connect")
    return f"cannot open the Zenoh session: {text.splitlines()[0] if text else exc!r}"
