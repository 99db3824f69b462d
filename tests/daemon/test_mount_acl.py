"""Who may say where the camera is, on the shipped secured bus (deploy/zenoh/): a session with the daemon's
identity (the shipped posed-daemon.json5 with a throwaway CA and certificates from make-certs.sh, TLS on
127.0.0.1, as ``posed run`` opens it) subscribes to ``posed/ROBOT/camera/mount``, and real clients built from
the shipped receiver.json5 put there. A watcher's certificate, and a listed receiver's (caregiver-app), never
reach it — a put there would move the robot's floor and could hide a fall — while the robot's own software
(CN robot-software) does, from this machine (the loopback interface) only; its put stops at the daemon, as an
acknowledgement does. Each denied client is shown connected first (it hears the daemon's status). The same
certificate connected over another interface, or through a fleet's router, is refused too (the router's link
carries the router's certificate): the robot's software must connect to the daemon itself, on 127.0.0.1
(deploy/fleet/README.md, "Who may say where the camera is")."""

from __future__ import annotations

import fcntl
import json
import os
import socket
import struct
import subprocess
import time
from pathlib import Path

import pytest
import zenoh

from posed.client import PosedClient, session_config
from tests.daemon.test_bus_security import DEPLOY, LISTED, _receiver, _render
from tests.daemon.zenoh_util import free_port

ROBOT = "mnt"
MOUNT = f"posed/{ROBOT}/camera/mount"
SOFTWARE = "robot-software"                 # the CN the shipped posed-daemon.json5 lists as the robot's software


def _certs(tmp_path: Path, *cns: str, san: str | None = None) -> Path:
    certs = tmp_path / "certs"
    env = {**os.environ, "POSED_TLS_SAN": san or ""}
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), *cns], capture_output=True, text=True,
                       timeout=60, env=env)
    assert r.returncode == 0, r.stderr
    return certs


def _daemon_identity(tmp_path: Path, certs: Path, listen: list[str]) -> zenoh.Session:
    """A session as the daemon opens it: the shipped posed-daemon.json5, then posed's mode and listen over it."""
    cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    return zenoh.open(session_config("peer", listen=listen, config_file=str(cfg)))


def _heard(daemon: zenoh.Session, sessions: dict[str, zenoh.Session]) -> None:
    """Each client hears the daemon's status: it is on the bus, so what it puts would be routed."""
    heard: set[str] = set()
    subs = [s.declare_subscriber(f"posed/{ROBOT}/status", lambda _s, name=name: heard.add(name))
            for name, s in sessions.items()]
    deadline = time.monotonic() + 20
    while heard != set(sessions):
        assert time.monotonic() < deadline, f"not on the bus: {sorted(set(sessions) - heard)}"
        daemon.put(f"posed/{ROBOT}/status", json.dumps({"format": "posed.status", "version": 1}))
        time.sleep(0.1)
    for sub in subs:
        sub.undeclare()


def _put_for(sessions: dict[str, zenoh.Session], got: list[str], seconds: float) -> None:
    """Every client puts its mount (``source`` = its name) ten times a second, through the client's API."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        for name, s in sessions.items():
            PosedClient(s).set_camera_mount(ROBOT, tilt_deg=10.0, roll_deg=0.0, height_m=1.0, source=name)
        time.sleep(0.1)
    time.sleep(0.5)


def test_only_the_robots_software_says_where_the_camera_is(tmp_path):
    certs = _certs(tmp_path, "watcher", LISTED, SOFTWARE)
    ep = f"tls/127.0.0.1:{free_port()}"
    daemon = _daemon_identity(tmp_path, certs, [ep])
    sessions: dict[str, zenoh.Session] = {}
    try:
        got: list[str] = []
        daemon.declare_subscriber(MOUNT, lambda s: got.append(json.loads(s.payload.to_string())["source"]))
        for cn in ("watcher", LISTED, SOFTWARE):
            sessions[cn] = _receiver(tmp_path, certs, cn, ep)
        # what a watcher subscribed to posed/** gets of the mounts (it must get none: they stop at the daemon)
        (tmp_path / "all").mkdir()
        sessions["watching all"] = _receiver(tmp_path / "all", certs, "watcher", ep)
        routed: list[str] = []
        sessions["watching all"].declare_subscriber(
            "posed/**", lambda s: routed.append(str(s.key_expr)) if str(s.key_expr) == MOUNT else None)
        _heard(daemon, sessions)

        _put_for({k: v for k, v in sessions.items() if k != "watching all"}, got, 3.0)
        assert set(got) == {SOFTWARE}, f"the daemon heard mounts from {sorted(set(got))}; only {SOFTWARE} may"
        assert got.count(SOFTWARE) >= 20, got              # ~30 put in 3 s
        assert routed == [], "the robot's mount was routed on to a watcher"
    finally:
        for s in sessions.values():
            s.close()
        daemon.close()


def _other_ipv4() -> str | None:
    """An IPv4 address of this machine on an interface other than loopback, or None."""
    for _, name in socket.if_nameindex():
        if name == "lo":
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                packed = fcntl.ioctl(s.fileno(), 0x8915, struct.pack("256s", name.encode()[:15]))  # SIOCGIFADDR
            except OSError:
                continue
        addr = socket.inet_ntoa(packed[20:24])
        if not addr.startswith("127."):
            return addr
    return None


def test_the_robots_software_certificate_from_another_interface_is_refused(tmp_path):
    """The same robot-software certificate, connected to the daemon's listener on another interface's address
    (as from another machine), reaches nothing; over 127.0.0.1 it does (the control, in the same session).
    Fails if the shipped subject "robot_software" drops its ``interfaces: ["lo"]``."""
    addr = _other_ipv4()
    if addr is None:
        pytest.skip("this machine has no IPv4 address outside loopback to connect from")
    certs = _certs(tmp_path, SOFTWARE, san=f"IP:{addr}")
    lo, other = f"tls/127.0.0.1:{free_port()}", f"tls/{addr}:{free_port()}"
    daemon = _daemon_identity(tmp_path, certs, [lo, other])
    sessions: dict[str, zenoh.Session] = {}
    try:
        got: list[str] = []
        daemon.declare_subscriber(MOUNT, lambda s: got.append(json.loads(s.payload.to_string())["source"]))
        for name, ep in (("over lo", lo), (f"over {addr}", other)):
            (tmp_path / name).mkdir()
            sessions[name] = _receiver(tmp_path / name, certs, SOFTWARE, ep)
        _heard(daemon, sessions)
        _put_for(sessions, got, 3.0)
        assert set(got) == {"over lo"}, got
    finally:
        for s in sessions.values():
            s.close()
        daemon.close()


def test_a_mount_through_a_router_is_refused_whoever_put_it(tmp_path):
    """The daemon (the shipped posed-daemon.json5, with what a deployer adds so that acknowledgements pass a
    fleet's router: the router's CN among the receivers, the daemon's subscriptions declared to it) joined to a
    TLS router on 127.0.0.1. A listed receiver's ack through the router reaches the daemon (the route is there),
    the robot software's mount through the router does not — it arrives on the router's link, with the router's
    certificate — while the same certificate connected to the daemon itself does (the control)."""
    certs = _certs(tmp_path, LISTED, SOFTWARE, "fleet-router")
    rep, dep = f"tls/127.0.0.1:{free_port()}", f"tls/127.0.0.1:{free_port()}"
    tls = {"root_ca_certificate": str(certs / "ca.pem"), "enable_mtls": True,
           **{f"{side}_{what}": str(certs / f"fleet-router.{ext}") for side in ("listen", "connect")
              for what, ext in (("certificate", "pem"), ("private_key", "key"))}}
    (tmp_path / "router.json5").write_text(json.dumps({"transport": {"link": {"tls": tls}}}))
    router = zenoh.open(session_config("router", listen=[rep], config_file=str(tmp_path / "router.json5")))
    cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    text = cfg.read_text()
    for old, new in (('cert_common_names: ["caregiver-app", "posed-admin"]',
                      'cert_common_names: ["caregiver-app", "posed-admin", "fleet-router"]'),
                     ('{ rules: ["watch", "state", "daemon_output"], subjects: ["tls_peers"] },',
                      '{ rules: ["watch", "state", "daemon_output", "subscriptions_out"], subjects: ["tls_peers"] },'),
                     ("    rules: [\n", '    rules: [\n      { id: "subscriptions_out", permission: "allow", '
                      'flows: ["egress"], messages: ["declare_subscriber"], key_exprs: ["posed/**"] },\n')):
        assert text.count(old) == 1, f"posed-daemon.json5 no longer has {old!r}"
        text = text.replace(old, new)
    cfg.write_text(text)
    daemon = zenoh.open(session_config("peer", listen=[dep], connect=[rep], config_file=str(cfg)))
    sessions: dict[str, zenoh.Session] = {}
    try:
        mounts: list[str] = []
        acks: list[str] = []
        daemon.declare_subscriber(MOUNT, lambda s: mounts.append(json.loads(s.payload.to_string())["source"]))
        daemon.declare_subscriber(f"posed/{ROBOT}/events/ack", lambda s: acks.append(s.payload.to_string()))
        for name, cn, ep in (("receiver via router", LISTED, rep), ("via router", SOFTWARE, rep),
                             ("direct", SOFTWARE, dep)):
            (tmp_path / name).mkdir()
            sessions[name] = _receiver(tmp_path / name, certs, cn, ep)
        _heard(daemon, sessions)
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            sessions["receiver via router"].put(f"posed/{ROBOT}/events/ack", "e1")
            for name in ("via router", "direct"):
                PosedClient(sessions[name]).set_camera_mount(ROBOT, down=[0, 1, 0], source=name)
            time.sleep(0.1)
        time.sleep(0.5)
        assert acks, "nothing came through the router: the test shows nothing"
        assert set(mounts) == {"direct"}, mounts
    finally:
        for s in sessions.values():
            s.close()
        daemon.close()
        router.close()
