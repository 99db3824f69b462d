"""A secured fleet on 127.0.0.1 (deploy/fleet/README.md, "A secured fleet"): a throwaway CA and certificates
made by deploy/zenoh/make-certs.sh, a zenoh-python session in router mode opened from the shipped
deploy/fleet/router-tls.json5 (the stand-in for zenohd: mutual TLS, the router's own access control), a real
``posed run`` configured from deploy/fleet/robot-tls.yaml with the shipped deploy/zenoh/posed-daemon.json5 (a
TLS listener on 127.0.0.1, joined to the router), replaying a real fall; and caregivers' stations and watchers,
each a client of the router with its own certificate, opened from the shipped receiver.json5 (and the fleet's
station.py given the caregiver's).

The chain of trust under test: the router admits each certificate for what it may do (a listed caregiver:
acknowledge and read the history; any other: watch), and the daemon admits the router's certificate for what
it relays. So a caregiver's acknowledgement through the router reaches the daemon (journal and history say who,
from the ack's ``by``) and the robot stops republishing; a watcher's is dropped at the router (the event stays
open and keeps being republished) and its history query gets no reply; no watcher ever reads an
acknowledgement; and nobody's camera mount passes the router, while the robot's software connected to the
daemon itself is heard (the control)."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh

from posed.client import PosedClient
from tests.daemon.zenoh_util import free_port
from tests.interop.daemons import ROOT, URFD, Daemon, fall_overrides, wait_for

FLEET = ROOT / "deploy" / "fleet"
DEPLOY = ROOT / "deploy" / "zenoh"
# the shipped templates (module constants, so that a check of this test can point them at broken copies)
ROUTER_JSON5 = FLEET / "router-tls.json5"
DAEMON_JSON5 = DEPLOY / "posed-daemon.json5"
RECEIVER_JSON5 = DEPLOY / "receiver.json5"
ROBOT_YAML = FLEET / "robot-tls.yaml"
INSTALLED_TLS_DIR = "/etc/posed/tls/"      # where the shipped templates look for the certificates
ROUTER = "posed-router"                    # the router's CN, which posed-daemon.json5 admits (subject "router")
CAREGIVER = "caregiver-app"                # a CN router-tls.json5 lists among its receivers
WATCHER = "watcher"                        # any other certificate of the CA
SOFTWARE = "robot-software"                # the robot's own software (camera/mount, on the robot only)
REPUBLISH_S = 2.0                          # zenoh.event_republish_s: an open event comes again this often


def _render(template: Path, out: Path, certs: Path, **replace: str) -> Path:
    """The shipped template with its certificate folder (and ``replace``'s texts) replaced."""
    text = template.read_text()
    assert INSTALLED_TLS_DIR in text, f"{template} no longer names {INSTALLED_TLS_DIR}"
    text = text.replace(INSTALLED_TLS_DIR, f"{certs}/")
    for old, new in replace.items():
        assert old in text, f"{template} no longer has {old!r}"
        text = text.replace(old, new)
    out.write_text(text)
    return out


def _router(tmp_path: Path, certs: Path, endpoint: str) -> zenoh.Session:
    """The fleet's router from the shipped router-tls.json5, listening on ``endpoint`` instead of 0.0.0.0."""
    cfg = zenoh.Config.from_file(str(_render(ROUTER_JSON5, tmp_path / "router-tls.json5", certs)))
    cfg.insert_json5("listen/endpoints", json.dumps([endpoint]))
    return zenoh.open(cfg)


def _party(tmp_path: Path, certs: Path, cn: str, endpoint: str, name: str | None = None) -> PosedClient:
    """A client holding the certificate of ``cn`` (the shipped receiver.json5, as the fleet's README says to
    copy it), connected to ``endpoint`` through the posed client."""
    d = tmp_path / f"party-{name or cn}"
    d.mkdir()
    for src, dst in (("ca.pem", "ca.pem"), (f"{cn}.pem", "receiver.pem"), (f"{cn}.key", "receiver.key")):
        shutil.copy(certs / src, d / dst)
    cfg = _render(RECEIVER_JSON5, d / "receiver.json5", d)
    return PosedClient.connect(endpoint, wait_s=30, config_file=str(cfg))


def _journal(state_dir: Path, event_id: str) -> list[tuple[str, float | None, str | None]]:
    """(state, acked_at, acked_by) of each of the event's messages in the daemon's journal."""
    with sqlite3.connect(state_dir / "events.sqlite3") as db:
        return db.execute("SELECT state, acked_at, acked_by FROM messages WHERE event_id = ? ORDER BY wall",
                          (event_id,)).fetchall()


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_a_caregiver_acknowledges_through_the_secured_router_and_a_watcher_cannot(tmp_path, shared_data):
    """Fails if posed-daemon.json5 does not admit the router's certificate (the caregiver's ack and history
    query never reach the daemon: no confirmation), if the router lists the watcher among its receivers (its
    ack acknowledges), or if the router passes acknowledgements on to watchers."""
    certs = tmp_path / "certs"
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), ROUTER, CAREGIVER, WATCHER, SOFTWARE],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    rep, dep = f"tls/127.0.0.1:{free_port()}", f"tls/127.0.0.1:{free_port()}"
    router = _router(tmp_path, certs, rep)
    daemon_cfg = _render(DAEMON_JSON5, tmp_path / "posed-daemon.json5", certs)
    robot = Daemon(tmp_path, "r1", shared_data / URFD / "urfd_02_fall.landmarks.jsonl", rep,
                   *fall_overrides(shared_data), f"zenoh.config_file={daemon_cfg}", f"zenoh.listen=[{dep}]",
                   f"zenoh.event_republish_s={REPUBLISH_S}", "pipeline.status_period_s=0.5",
                   "falls.camera_mount_from_bus=true", config=ROBOT_YAML)
    parties: list[PosedClient] = []
    lock = threading.Lock()
    events: list[tuple[float, str, str]] = []       # (monotonic, id, state) of each fall message at the station
    statuses: list[dict] = []
    acks_seen: list[str] = []                       # what a watcher subscribed to posed/** reads of the acks

    def party(cn: str, endpoint: str = rep, name: str | None = None) -> PosedClient:
        parties.append(_party(tmp_path, certs, cn, endpoint, name))
        return parties[-1]

    try:
        station = party(CAREGIVER)
        station.on_event("r1", lambda _r, e: _add(lock, events, (time.monotonic(), e.id, e.state)))
        station.on_status("r1", lambda _r, s: _add(lock, statuses, s.raw))
        watching = party(WATCHER, name="watching-all")
        watching.session.declare_subscriber(
            "posed/**", lambda s: _add(lock, acks_seen, s.payload.to_string())
            if str(s.key_expr).endswith("/events/ack") else None)
        watcher = party(WATCHER)
        robot.start()
        wait_for(lambda: station.robots() == ["r1"], 180, "the robot up, seen through the router", robot)

        # the real fall reaches the station through the router: its first message, then its alarm (the person
        # is still down when the recording ends, soon after the impact: no message of it comes after the alarm)
        event_id = wait_for(lambda: [i for _, i, _ in _copy(lock, events)], 180, "the fall event", robot)[0]
        wait_for(lambda: "alarm" in {s for _, i, s in _copy(lock, events) if i == event_id}, 60,
                 "the fall's alarm", robot)
        states = sorted(s for s, _, _ in _journal(robot.state_dir, event_id))
        assert {"falling", "alarm"} <= set(states), states

        # the caregiver reads the history through the router: open
        history = wait_for(lambda: [h for h in station.history("r1") if h.event.id == event_id], 20,
                           "the event in the history read through the router")
        assert sorted(h.event.state for h in history) == states
        assert all(h.acked_at is None and h.robot == "r1" for h in history)
        # the fleet's station program, given the caregiver's config, lists it as open
        out = tmp_path / "station.out"
        with open(out, "w") as f:
            prog = subprocess.Popen([sys.executable, "-u", str(FLEET / "station.py"), rep,
                                     str(tmp_path / f"party-{CAREGIVER}" / "receiver.json5")], cwd=ROOT, stdout=f,
                                    stderr=subprocess.STDOUT)
        try:
            wait_for(lambda: f"open: r1 alarm {event_id}" in out.read_text() and "robot r1 up" in out.read_text(),
                     30, "station.py listing the open event", robot)
        finally:
            prog.kill()
            prog.wait(10)

        # a watcher: its ack is dropped at the router, and its history query gets no reply
        for _ in range(10):
            watcher.ack("r1", event_id, by="a watcher")
            time.sleep(0.2)
        t_refused = time.monotonic()
        wait_for(lambda: [t for t, i, _ in _copy(lock, events) if i == event_id and t > t_refused + REPUBLISH_S],
                 6 * REPUBLISH_S, "the event republished after the watcher's ack", robot)
        assert all(acked is None for _, acked, _ in _journal(robot.state_dir, event_id)), "a watcher acknowledged"
        assert all(h.acked_at is None for h in station.history("r1") if h.event.id == event_id)
        assert watcher.history("r1") == []

        # the caregiver acknowledges through the router: the daemon has it, with who said so
        assert station.ack("r1", event_id, by="Anna (caregiver)", confirm_s=20.0), "the ack was not confirmed"
        t_acked = time.monotonic()
        journal = _journal(robot.state_dir, event_id)
        assert journal and all(acked is not None and by == "Anna (caregiver)" for _, acked, by in journal), journal
        after = [h for h in station.history("r1") if h.event.id == event_id]
        assert after and all(h.acked_at is not None and h.acked_by == "Anna (caregiver)" for h in after)
        # ... and stops republishing what was acknowledged (the robot keeps running and publishing)
        n = len(_copy(lock, statuses))
        time.sleep(3 * REPUBLISH_S)
        acked = {s for s, _, _ in journal}
        late = [(s, t - t_acked) for t, i, s in _copy(lock, events) if i == event_id and s in acked
                and t > t_acked + 1.0]
        assert late == [], f"acknowledged messages republished after the ack: {late}"
        assert len(_copy(lock, statuses)) > n, "the robot stopped publishing"
        assert robot.proc.poll() is None

        # nobody's camera mount passes the router, the robot software's neither; on the daemon's own listener
        # (127.0.0.1) the same certificate is heard (the control)
        software_via_router = party(SOFTWARE, name="software-via-router")
        for _ in range(20):
            software_via_router.set_camera_mount("r1", tilt_deg=10.0, roll_deg=0.0, height_m=1.0, source="router")
            station.set_camera_mount("r1", tilt_deg=10.0, roll_deg=0.0, height_m=1.0, source="station")
            time.sleep(0.1)
        n = len(_copy(lock, statuses))
        wait_for(lambda: len(_copy(lock, statuses)) >= n + 4, 10, "four more statuses", robot)
        assert _mounts_received(_copy(lock, statuses)[-1]) == 0, "a camera mount came through the router"
        software = party(SOFTWARE, dep, name="software-direct")
        for _ in range(20):
            software.set_camera_mount("r1", tilt_deg=10.0, roll_deg=0.0, height_m=1.0, source="direct")
            time.sleep(0.1)
        wait_for(lambda: _mounts_received(_copy(lock, statuses)[-1]) > 0, 10,
                 "the robot software's mount on the daemon's own listener", robot)

        # no watcher ever read an acknowledgement (the router passes them to the daemons only)
        assert acks_seen == [], acks_seen
    finally:
        for p in parties:
            p.close()
        robot.stop()
        router.close()


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_two_robots_with_one_robot_id_find_each_other_through_the_secured_router(tmp_path, shared_data):
    """Two real ``posed run`` with one robot id, each a client of the TLS router (deploy/fleet/robot-client.yaml's
    layout with the shipped posed-daemon.json5: everything through the router): each says ``robot_id_in_use``
    naming the other, and a station reads it in the status. Before the second one starts, a watcher's fake
    daemon token through the router is not heard (the router admits such tokens from CN posed-daemon only).
    Fails if posed-daemon.json5 does not let the router pass on the daemons' tokens, or if the router admits
    tokens from any certificate."""
    certs = tmp_path / "certs"
    r = subprocess.run(["sh", str(DEPLOY / "make-certs.sh"), str(certs), ROUTER, CAREGIVER, WATCHER],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    rep = f"tls/127.0.0.1:{free_port()}"
    router = _router(tmp_path, certs, rep)
    daemon_cfg = _render(DAEMON_JSON5, tmp_path / "posed-daemon.json5", certs)
    clip = shared_data / URFD / "urfd_16_adl.landmarks.jsonl"
    light = ("source.loop=true", "source.realtime=true", "pipeline.target_fps=5", "pipeline.status_period_s=0.5",
             f"zenoh.config_file={daemon_cfg}", "zenoh.listen=[]")
    a, b = (Daemon(tmp_path / name, "dup", clip, rep, *light, config=FLEET / "robot-client.yaml")
            for name in ("a", "b"))
    parties: list[PosedClient] = []
    lock = threading.Lock()
    statuses: list[dict] = []
    try:
        parties.append(_party(tmp_path, certs, CAREGIVER, rep))
        station = parties[-1]
        station.on_status("dup", lambda _r, st: _add(lock, statuses, st.raw))
        parties.append(_party(tmp_path, certs, WATCHER, rep))
        watcher = parties[-1].session
        heard: list[str] = []
        _fakes = [watcher.liveliness().declare_token("posed/dup/alive/fake.1.host"),
                  watcher.liveliness().declare_subscriber("posed/dup/alive/*",
                                                          lambda t: _add(lock, heard, str(t.key_expr)), history=True)]
        a.start()
        own = f".{a.proc.pid}."
        wait_for(lambda: any(own in k for k in _copy(lock, heard)), 120,
                 "a's own token, heard by the watcher through the router", a)
        n = len(_copy(lock, statuses))
        wait_for(lambda: len(_copy(lock, statuses)) >= n + 8, 20, "eight more statuses (4 s)", a)
        assert _logged(a, "robot_id_in_use") == [], "a watcher's token through the router faked a second daemon"
        assert all((st.get("zenoh") or {}).get("robot_id_conflict") is None for st in _copy(lock, statuses))

        b.start()
        said_a = wait_for(lambda: _logged(a, "robot_id_in_use"), 120, "a saying robot_id_in_use", a)
        said_b = wait_for(lambda: _logged(b, "robot_id_in_use"), 60, "b saying robot_id_in_use", b)
        assert any(f"pid {b.proc.pid} on host" in o for o in said_a[0]["other_daemons"]), said_a
        assert any(f"pid {a.proc.pid} on host" in o for o in said_b[0]["other_daemons"]), said_b
        wait_for(lambda: any((st.get("zenoh") or {}).get("robot_id_conflict") for st in _copy(lock, statuses)), 30,
                 "the conflict in the status the station reads through the router", a)
        b.stop()
        wait_for(lambda: _logged(a, "robot_id_conflict_ended"), 30, "a saying the conflict ended", a)
        assert a.proc.poll() is None
    finally:
        for p in parties:
            p.close()
        for d in (b, a):
            d.stop()
        router.close()


def _logged(daemon: Daemon, event: str) -> list[dict]:
    """The daemon's JSON log lines whose event is ``event``."""
    found = []
    for line in (daemon.dir / f"out{daemon.runs}.log").read_text(errors="replace").splitlines():
        if line.startswith("{") and f'"{event}"' in line:
            obj = json.loads(line)
            if obj.get("event") == event:
                found.append(obj)
    return found


def _add(lock: threading.Lock, into: list, item) -> None:
    with lock:
        into.append(item)


def _copy(lock: threading.Lock, of: list) -> list:
    with lock:
        return list(of)


def _mounts_received(status: dict) -> int:
    return ((status.get("falls") or {}).get("geometry") or {}).get("robot_mount", {}).get("received", 0)
