"""How the command line reaches a running daemon over Zenoh: the endpoint and robot id come from the same
config the daemon reads (``--config``, ``$POSED_CONFIG``, /etc/posed/config.yaml, the embedded default)."""

from __future__ import annotations

import dataclasses
import sys
import time

from posed.daemon.config import Config


def open_client(cfg: Config, endpoints: tuple[str, ...], wait_s: float, who: str):
    """A client session to ``endpoints`` (with the config's ``zenoh.config_file``: TLS, credentials), retried
    for ``wait_s``; None after a message on stderr when it cannot connect."""
    import zenoh

    from posed.daemon.bus.session import ZenohConfigError, build_config

    zcfg = dataclasses.replace(cfg.zenoh, mode="client", listen=(), connect=endpoints, multicast_scouting=False)
    if not endpoints:
        print(f"{who}: no endpoint to reach the daemon (zenoh.listen and zenoh.connect are empty); give one "
              "with --connect", file=sys.stderr)
        return None
    deadline = time.monotonic() + wait_s
    while True:
        try:
            return zenoh.open(build_config(zcfg))
        except ZenohConfigError as exc:
            print(f"{who}: {exc}", file=sys.stderr)
            return None
        except Exception as exc:  # zenoh's ZError: nobody listens there (yet)
            if time.monotonic() >= deadline:
                print(f"{who}: cannot connect to {', '.join(endpoints)}: {str(exc).splitlines()[0]}\n"
                      "  is the daemon running (systemctl status posed, or posed run)? Give its endpoint with "
                      "--connect, or its config with --config", file=sys.stderr)
                return None
            time.sleep(0.25)
