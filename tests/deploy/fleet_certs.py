"""A secured fleet with one certificate per robot, for the tests: certificates from deploy/zenoh/make-certs.sh
(``--robot``), configs from deploy/fleet/make-acl.py, and the fleet's router (a zenoh-python session in router
mode, the stand-in for zenohd, as in tests/interop/test_fleet_tls.py) on 127.0.0.1, multicast scouting off."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import zenoh

from tests.interop.test_fleet_tls import _render

ROOT = Path(__file__).resolve().parents[2]
MAKE_CERTS = ROOT / "deploy" / "zenoh" / "make-certs.sh"
MAKE_ACL = ROOT / "deploy" / "fleet" / "make-acl.py"
ROUTER = "posed-router"          # the router's CN, which posed-daemon.json5 admits (subject "router")
CAREGIVER = "caregiver-app"      # a receiver the router lists by default


def make_certs(certs: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["sh", str(MAKE_CERTS), str(certs), *args], capture_output=True, text=True, timeout=120)


def make_acl(out: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(MAKE_ACL), str(out), *args], capture_output=True, text=True,
                          timeout=60)


def fleet_certs(certs: Path, robots: tuple[str, ...], *cns: str) -> Path:
    """The CA, the router's and the CNs' certificates, one per robot (certs/robots/ROBOT/) and the shared one
    (certs/posed-daemon.*, what the shipped setup gives every robot)."""
    r = make_certs(certs, ROUTER, CAREGIVER, *cns, *(a for robot in robots for a in ("--robot", robot)))
    assert r.returncode == 0, r.stderr
    r = make_certs(certs)       # the CA exists: only the shared posed-daemon certificate is added
    assert r.returncode == 0, r.stderr
    return certs


def zenoh_json(path: Path) -> dict:
    """A config file as Zenoh reads it (its own JSON5 parser, defaults filled in), the parts the fleet sets."""
    cfg = zenoh.Config.from_file(str(path))
    return {k: json.loads(cfg.get_json(k)) for k in ("mode", "listen", "connect", "scouting", "transport",
                                                     "access_control")}


def router(tmp_path: Path, config: Path, certs: Path, endpoint: str) -> zenoh.Session:
    """The fleet's router from ``config`` (a shipped or generated router-tls.json5), its certificates in
    ``certs``, listening on ``endpoint`` instead of 0.0.0.0."""
    cfg = zenoh.Config.from_file(str(_render(config, tmp_path / f"router-{config.parent.name}.json5", certs)))
    cfg.insert_json5("listen/endpoints", json.dumps([endpoint]))
    return zenoh.open(cfg)
