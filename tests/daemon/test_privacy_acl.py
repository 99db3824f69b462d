"""Who may pause the watching, on the shipped secured bus (deploy/zenoh/posed-daemon.json5 with a throwaway CA
and certificates from make-certs.sh): a real ``posed run`` replaying the squat video on a TLS listener on
127.0.0.1, queried on ``posed/ROBOT/privacy/pause`` through ``PosedClient`` by real clients built from the shipped
receiver.json5. A watcher's certificate gets no answer and pauses nothing (a pause blinds the fall monitor); a
listed receiver (caregiver-app) and the robot's own software (CN robot-software, over loopback) may pause and
resume. Each refused client is shown on the bus first (it hears the daemon's status)."""

from __future__ import annotations

import time

import pytest

from posed.client import PosedClient
from posed.client.api import NoAnswerError
from tests.daemon.privacy_util import SQUAT, PosedRun, wait
from tests.daemon.test_bus_security import DEPLOY, LISTED, _receiver, _render, _statuses
from tests.daemon.test_mount_acl import SOFTWARE, _certs
from tests.daemon.zenoh_util import free_port

ROBOT = "pacl"


def test_only_the_robots_software_and_listed_receivers_pause(tmp_path, shared_data):
    certs = _certs(tmp_path, "watcher", LISTED, SOFTWARE)
    ep = f"tls/127.0.0.1:{free_port()}"
    daemon_cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    run = PosedRun(tmp_path, "d", f"{shared_data / SQUAT}?loop=true", ROBOT, 7447, f"zenoh.listen=[{ep}]",
                   f"zenoh.config_file={daemon_cfg}")
    sessions = {}
    try:
        for cn in ("watcher", LISTED, SOFTWARE):
            sessions[cn] = _receiver(tmp_path, certs, cn, ep)
        got, sub = _statuses(sessions["watcher"], ROBOT)
        wait(lambda: got, 120, "the watcher hearing the daemon's status", run)     # on the bus, listening
        clients = {cn: PosedClient(s) for cn, s in sessions.items()}
        with pytest.raises(NoAnswerError):
            clients["watcher"].pause(600, "watcher", robot=ROBOT, timeout=3.0)
        time.sleep(1.5)
        assert all(not s["privacy"]["paused"] for s in got[-2:]), got[-1]["privacy"]
        assert not run.events("privacy_pause_started")

        state = clients[LISTED].pause(600, "carer", robot=ROBOT, timeout=5.0)
        assert state.paused and state.by == "carer"
        with pytest.raises(NoAnswerError):
            clients["watcher"].resume("watcher", robot=ROBOT, timeout=3.0)
        assert clients[SOFTWARE].resume("voice", robot=ROBOT, timeout=5.0).paused is False
        assert clients[SOFTWARE].pause(60, "voice", robot=ROBOT, timeout=5.0).paused
        assert [e["by"] for e in run.events("privacy_pause_started")] == ["carer", "voice"]
        ended = run.events("privacy_pause_ended")
        assert [(e["ended"], e["resumed_by"]) for e in ended] == [("resumed", "voice")]
        sub.undeclare()
    finally:
        for s in sessions.values():
            s.close()
        code = run.stop()
    assert code == 0


def test_through_the_secured_router_a_listed_caregiver_pauses_and_a_watcher_cannot(tmp_path, shared_data):
    """The shipped deploy/fleet/router-tls.json5 (a zenoh-python router standing in for zenohd) and the daemon
    joined to it (as deploy/fleet/robot-tls.yaml does): a listed caregiver's pause passes the router and the
    daemon's admission of the router; a watcher's is dropped at the router (no answer, nothing paused)."""
    from tests.interop.test_fleet_tls import CAREGIVER, ROUTER, WATCHER, _party, _router

    certs = _certs(tmp_path, ROUTER, CAREGIVER, WATCHER)
    rep, dep = f"tls/127.0.0.1:{free_port()}", f"tls/127.0.0.1:{free_port()}"
    router = _router(tmp_path, certs, rep)
    daemon_cfg = _render(DEPLOY / "posed-daemon.json5", tmp_path / "posed-daemon.json5", certs)
    run = PosedRun(tmp_path, "d", f"{shared_data / SQUAT}?loop=true", ROBOT, 7447, f"zenoh.listen=[{dep}]",
                   f"zenoh.connect=[{rep}]", f"zenoh.config_file={daemon_cfg}")
    parties: list[PosedClient] = []
    try:
        parties += [_party(tmp_path, certs, CAREGIVER, rep), _party(tmp_path, certs, WATCHER, rep)]
        carer, watcher = parties
        statuses: list[dict] = []
        watcher.on_status(ROBOT, lambda _r, s: statuses.append(s.raw))
        wait(lambda: statuses, 120, "the watcher hearing the daemon through the router", run)
        with pytest.raises(NoAnswerError):
            watcher.pause(600, "watcher", robot=ROBOT, timeout=3.0)
        assert not run.events("privacy_pause_started")
        state = carer.pause(600, "carer", robot=ROBOT, timeout=5.0)
        assert state.paused and state.by == "carer"
        wait(lambda: statuses and statuses[-1]["state"] == "paused", 10, "the status through the router: paused",
             run)
        assert carer.resume("carer", robot=ROBOT, timeout=5.0).paused is False
    finally:
        for p in parties:
            p.close()
        code = run.stop()
        router.close()
    assert code == 0
