"""The shipped secured-bus configuration (deploy/zenoh/): a throwaway CA and certificates made by
deploy/zenoh/make-certs.sh (Debian's openssl), the real supervisor and publisher stage (scripted fall) on a
TLS listener on 127.0.0.1 with the shipped access control, and real Zenoh clients built from the shipped
receiver config. A certificate whose common name is listed acknowledges events and reads the history; one
that is not listed only watches (its ack changes nothing, its history query gets no reply); a client without
a certificate, or without TLS, cannot connect at all."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from tests.daemon.harness import Harness
from tests.daemon.plan_stages import FALL_OVERRIDES
from tests.daemon.redteam_util import until
from tests.daemon.zenoh_util import config, free_port

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy" / "zenoh"
INSTALLED_TLS_DIR = "/etc/posed/tls/"       # where the shipped templates look for the certificates
LISTED = "caregiver-app"                    # a common name the shipped posed-daemon.json5 lists as receiver


def _render(template: Path, out: Path, tls_dir: Path, endpoint: str | None = None) -> Path:
    """The shipped template with its certificate folder (and, for a receiver, its endpoint) replaced."""
    text = template.read_text()
    assert INSTALLED_TLS_DIR in text, f"{template} no longer names {INSTALLED_TLS_DIR}"
    text = text.replace(INSTALLED_TLS_DIR, f"{tls_dir}/")
    if endpoint is not None:
        assert "tls/127.0.0.1:7447" in text
        text = text.replace("tls/127.0.0.1:7447", endpoint)
    out.write_text(text)
    return out


def _receiver(tmp_path: Path, certs: Path, cn: str, endpoint: str) -> zenoh.Session:
    """A client opened from the shipped receiver.json5, holding the certificate of ``cn``."""
    d = tmp_path / f"client-{cn}"
    d.mkdir()
    shutil.copy(certs / "ca.pem", d / "ca.pem")
    shutil.copy(certs / f"{cn}.pem", d / "receiver.pem")
    shutil.copy(certs / f"{cn}.key", d / "receiver.key")
    cfg = _render(DEPLOY / "receiver.json5", d / "receiver.json5", d, endpoint)
    deadline = time.monotonic() + 30
    while True:         # the daemon may still be starting
        try:
            return zenoh.open(zenoh.Config.from_file(str(cfg)))
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)



def _statuses(session: zenoh.Session, robot: str) -> tuple[list, object]:
    got: list = []
    sub = session.declare_subscriber(f"posed/{robot}/status", lambda s: got.append(json.loads(s.payload.to_string())))
    return got, sub


def _history(session: zenoh.Session, robot: str) -> list[str]:
    replies = session.get(f"posed/{robot}/events/history/**?limit=10",
                          consolidation=zenoh.ConsolidationMode.NONE, timeout=3)
    return sorted(str(r.ok.key_expr) for r in replies if r.ok is not None)


def test_only_listed_receivers_ack_and_read_history(tmp_path):
    assert shutil.which("openssl"), "Debian's openssl is missing: deploy/bootstrap.sh installs it"
    certs = tmp_path / "certs"
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), LISTED, "stranger"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert (certs / "ca.key").stat().st_mode & 0o077 == 0, "private keys must not be readable by others"
    daemon_cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    ep = f"tls/127.0.0.1:{free_port()}"
    h = Harness(tmp_path, f"zenoh.listen=[{ep}]", f"zenoh.config_file={daemon_cfg}",
                f"pipeline.state_dir={tmp_path / 'state'}", "robot_id=sec", "zenoh.event_republish_s=600",
                *FALL_OVERRIDES, publisher=True)
    try:
        (tmp_path / "watching").mkdir()
        stranger_all = _receiver(tmp_path / "watching", certs, "stranger", ep)
        seen_acks: list[str] = []        # what an unlisted certificate subscribed to posed/** gets of the acks
        _all = stranger_all.declare_subscriber("posed/**", lambda s: seen_acks.append(s.payload.to_string())
                                               if str(s.key_expr).endswith("/events/ack") else None)
        with _receiver(tmp_path, certs, "stranger", ep) as stranger:
            # an unlisted certificate from the same CA may watch: it gets the status ...
            statuses, _sub = _statuses(stranger, "sec")
            until(lambda: any(s.get("events", {}).get("unacknowledged", 0) >= 3 for s in statuses), 60,
                   "three unacknowledged fall events in the status (seen by the unlisted client)")
            # ... but its history query is refused (no reply) and its ack has no effect
            assert _history(stranger, "sec") == []
            event_id = _journal(tmp_path)[0][0]
            stranger.put("posed/sec/events/ack", event_id)
            stranger.put("posed/sec/events/ack", json.dumps({"id": event_id}))
            n = len(statuses)
            until(lambda: len(statuses) >= n + 5, 10, "five more status messages")   # 5 x 0.2 s periods
            assert statuses[-1]["events"]["unacknowledged"] == 3
            assert all(acked is None for _, acked in _journal(tmp_path)), "an unlisted client acknowledged"

        with _receiver(tmp_path, certs, LISTED, ep) as listed:
            statuses, _sub = _statuses(listed, "sec")
            keys = _history(listed, "sec")
            assert keys == sorted(f"posed/sec/events/history/{event_id}/{st}"
                                  for st in ("falling", "on_floor", "alarm"))
            # the documented way for an administrator: `posed events ack` with a receiver config holding a
            # listed certificate (its session takes zenoh.config_file like the daemon's)
            r = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", event_id, "--connect", ep,
                                "--robot", "sec", "--journal", str(tmp_path / "state" / "events.sqlite3"),
                                "--set", f"zenoh.config_file={tmp_path / f'client-{LISTED}' / 'receiver.json5'}"],
                               cwd=ROOT, capture_output=True, text=True, timeout=60)
            assert r.returncode == 0, r.stdout + r.stderr
            until(lambda: statuses and statuses[-1]["events"]["unacknowledged"] == 0, 10, "the listed ack")
            assert all(acked is not None for _, acked in _journal(tmp_path))
            listed.put("posed/sec/events/ack", json.dumps({"id": event_id, "by": "caregiver"}))
            time.sleep(1.0)
        # the listed receivers' acknowledgements stop at the daemon: an unlisted watcher of posed/** never
        # sees them (the red-team's finding: it did)
        assert seen_acks == [], seen_acks
        _all.undeclare()
        stranger_all.close()

        # no certificate at all, or plain TCP to the TLS port: no session
        nocert = tmp_path / "nocert.json5"
        nocert.write_text(json.dumps({"mode": "client", "connect": {"endpoints": [ep]},
                                      "scouting": {"multicast": {"enabled": False}},
                                      "transport": {"link": {"tls": {"root_ca_certificate": str(certs / "ca.pem")}}}}))
        with pytest.raises(zenoh.ZError):
            zenoh.open(zenoh.Config.from_file(str(nocert)))
        with pytest.raises(zenoh.ZError):
            zenoh.open(config("client", connect=[ep.replace("tls/", "tcp/")]))
        assert h.proc.poll() is None
        code, _, err, _ = h.stop()
        assert code == 0, err
    finally:
        if h.proc.poll() is None:
            h.stop()


def _journal(tmp_path: Path) -> list[tuple[str, float | None]]:
    with sqlite3.connect(tmp_path / "state" / "events.sqlite3") as db:
        return db.execute("SELECT event_id, acked_at FROM messages ORDER BY wall").fetchall()


def test_two_daemons_with_one_robot_id_find_each_other_on_the_secured_bus(tmp_path, shared_data):
    """Two real `posed run` daemons with one robot id and the shipped posed-daemon.json5 (mutual TLS, access
    control), the second connected to the first: each says ``robot_id_in_use`` naming the other, and a listed
    receiver reads it in the status. Fails without the access-control rules for ``posed/*/alive/*`` (the
    daemons' own tokens and their liveliness subscribers were denied: nothing was said), or without the
    daemon's connect certificate (the second one could not connect at all)."""
    from tests.daemon.robots_util import Daemon, stop_all, wait

    certs = tmp_path / "certs"
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), LISTED], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    daemon_cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    ports = free_port(), free_port()
    eps = [f"tls/127.0.0.1:{p}" for p in ports]
    tls = ("--set", f"zenoh.config_file={daemon_cfg}")
    a = Daemon(tmp_path, "a", "dup", ports[0], shared_data, extra=(*tls, "--set", f"zenoh.listen=[{eps[0]}]"))
    b = None
    try:
        a.wait_log("zenoh_open", 90)
        b = Daemon(tmp_path, "b", "dup", ports[1], shared_data,
                   extra=(*tls, "--set", f"zenoh.listen=[{eps[1]}]", "--set", f"zenoh.connect=[{eps[0]}]"))
        said_a, said_b = a.wait_log("robot_id_in_use", 60), b.wait_log("robot_id_in_use", 60)
        assert any(f"pid {b.pid} on host" in o for o in said_a[0]["other_daemons"]), said_a
        assert any(f"pid {a.pid} on host" in o for o in said_b[0]["other_daemons"]), said_b
        with _receiver(tmp_path, certs, LISTED, eps[0]) as listed:
            statuses, _sub = _statuses(listed, "dup")
            wait(lambda: any((s.get("zenoh") or {}).get("robot_id_conflict") for s in statuses), 30,
                 "the conflict in the status a listed receiver reads", a)
        stop_all(b)
        a.wait_log("robot_id_conflict_ended", 30)
        assert a.proc.poll() is None
    finally:
        stop_all(*(d for d in (b, a) if d is not None))


def test_a_watching_certificate_cannot_fake_a_second_daemon(tmp_path, shared_data):
    """A real `posed run` with the shipped posed-daemon.json5, and clients from the shipped receiver.json5: an
    unlisted (watching) certificate and a listed receiver's each declare a token ``posed/ROBOT/alive/<instance>``
    and follow ``posed/ROBOT/alive/*``, as a second daemon would; for seconds the daemon says nothing
    (no ``robot_id_in_use``, ``zenoh.robot_id_conflict`` null in the status a listed receiver reads). Control:
    the same token from a client holding the daemons' certificate (CN posed-daemon) is a conflict at once, and
    its end is said. Fails if the access control admits ``posed/*/alive/*`` tokens from any other certificate
    (e.g. the policy of "daemon_tokens_in" given the subject "tls_peers")."""
    from tests.daemon.robots_util import Daemon, stop_all, wait

    certs = tmp_path / "certs"
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), LISTED, "watcher"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    daemon_cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    port = free_port()
    ep = f"tls/127.0.0.1:{port}"
    a = Daemon(tmp_path, "a", "solo", port, shared_data,
               extra=("--set", f"zenoh.config_file={daemon_cfg}", "--set", f"zenoh.listen=[{ep}]"))
    sessions: list[zenoh.Session] = []
    try:
        a.wait_log("zenoh_open", 90)
        listed = _receiver(tmp_path, certs, LISTED, ep)
        sessions.append(listed)
        statuses, _sub = _statuses(listed, "solo")
        watcher = _receiver(tmp_path, certs, "watcher", ep)
        sessions.append(watcher)
        seen: dict[str, str] = {}           # what the watcher's liveliness subscriber hears: key -> kind
        _fakes = [watcher.liveliness().declare_token("posed/solo/alive/fake.1.host"),
                  watcher.liveliness().declare_subscriber(
                      "posed/solo/alive/*", lambda s: seen.__setitem__(str(s.key_expr), str(s.kind)), history=True),
                  listed.liveliness().declare_token("posed/solo/alive/fake.2.host")]
        # the watcher is really on the bus and may watch: it hears the daemon's own token (subscriber and query)
        own = f".{a.pid}."
        wait(lambda: any(own in k for k in seen), 20, "the daemon's own token, heard by the watcher", a)
        replies = watcher.liveliness().get("posed/solo/alive/*", timeout=3)
        assert any(own in str(r.ok.key_expr) for r in replies if r.ok is not None)
        n = len(statuses)
        wait(lambda: len(statuses) >= n + 8, 20, "eight more status messages (4 s)", a)    # 0.5 s period
        assert a.events("robot_id_in_use") == [], "a watching certificate faked a second daemon"
        assert all((s.get("zenoh") or {}).get("robot_id_conflict") is None for s in statuses), statuses[-1]
        assert "robot_id_conflict" in statuses[-1]["zenoh"], statuses[-1]["zenoh"]

        # control: the daemons' certificate (as a second daemon holds it) is heard at once, and alone
        with _receiver(tmp_path, certs, "posed-daemon", ep) as daemon_cert:
            token = daemon_cert.liveliness().declare_token("posed/solo/alive/other.3.host")
            said = a.wait_log("robot_id_in_use", 20)
            assert said[0]["other_daemons"] == ["pid 3 on host host (Zenoh id other)"], said
            wait(lambda: any((s.get("zenoh") or {}).get("robot_id_conflict") for s in statuses), 10,
                 "the conflict in the status a listed receiver reads", a)
            token.undeclare()
            a.wait_log("robot_id_conflict_ended", 20)
        assert a.proc.poll() is None
    finally:
        for s in sessions:
            s.close()
        stop_all(a)
