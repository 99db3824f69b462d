"""One certificate per robot, end to end: certificates from deploy/zenoh/make-certs.sh ``--robot``, the router's
and each robot's config from deploy/fleet/make-acl.py, the router a zenoh-python session in router mode (the
stand-in for zenohd) over TLS on 127.0.0.1, two real ``posed run`` (robots A and B, deploy/fleet/robot-tls.yaml)
replaying real recordings, and a caregiver's station through the router (the posed client, the shipped
receiver.json5).

A's poses and its fall event reach the caregiver under posed/A; then a session holding A's certificate replays
them on robot B's keys (what a compromised robot A would do) and shows B's liveliness token: the caregiver never
receives any of it, while B's own daemon keeps being heard. And two daemons given one robot id on one machine,
each with that robot's generated config and certificate, still find each other (docs/daemon.md, "Several
daemons")."""

from __future__ import annotations

import json
import threading
import time

import pytest

from tests.daemon.zenoh_util import free_port
from tests.deploy.fleet_certs import CAREGIVER, fleet_certs, make_acl, router
from tests.interop.daemons import URFD, Daemon, fall_overrides, wait_for
from tests.interop.test_fleet_tls import FLEET, _party, _render


def _as_b(payload: str) -> str:
    """A's message as robot B's: the robot is named by the key; a ``robot`` field, if any, is changed too."""
    obj = json.loads(payload)
    if isinstance(obj, dict) and "robot" in obj:
        obj["robot"] = "B"
    return json.dumps(obj)


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_robot_a_is_heard_as_a_and_its_certificate_cannot_speak_for_b(tmp_path, shared_data):
    """Fails if the router's config lets A's certificate put on posed/B (the forged fall, or the forged pose,
    reaches the caregiver as robot B's) or show a token posed/B/alive/*; or if the generated configs lose what
    the robots need (A's fall, A's poses, B's status never arrive, or the daemons cannot join the router)."""
    certs = fleet_certs(tmp_path / "certs", ("A", "B"))
    r = make_acl(tmp_path / "acl", "--robot", "A", "--robot", "B")
    assert r.returncode == 0, r.stderr
    rep = f"tls/127.0.0.1:{free_port()}"
    rt = router(tmp_path, tmp_path / "acl" / "router-tls.json5", certs, rep)
    cfg = {x: _render(tmp_path / "acl" / x / "posed-daemon.json5", tmp_path / f"posed-daemon-{x}.json5",
                      certs / "robots" / x) for x in "AB"}
    a = Daemon(tmp_path, "A", shared_data / URFD / "urfd_02_fall.landmarks.jsonl", rep, *fall_overrides(shared_data),
               f"zenoh.config_file={cfg['A']}", f"zenoh.listen=[tls/127.0.0.1:{free_port()}]",
               "pipeline.status_period_s=0.5", config=FLEET / "robot-tls.yaml")
    b = Daemon(tmp_path, "B", shared_data / URFD / "urfd_16_adl.landmarks.jsonl", rep, "source.loop=true",
               "source.realtime=true", "pipeline.target_fps=5", "pipeline.status_period_s=0.5",
               f"zenoh.config_file={cfg['B']}", f"zenoh.listen=[tls/127.0.0.1:{free_port()}]",
               config=FLEET / "robot-tls.yaml")
    lock = threading.Lock()
    seen: dict[str, list] = {"A/fall": [], "A/event": [], "A/pose": [], "B/event": [], "B/raw": [], "B/status": [],
                             "alive": []}

    def add(what: str, item) -> None:
        with lock:
            seen[what].append(item)

    def got(what: str) -> list:
        with lock:
            return list(seen[what])

    parties = []
    try:
        parties.append(_party(tmp_path, certs, CAREGIVER, rep))
        station = parties[-1]
        s = station.session
        subs = [s.declare_subscriber("posed/A/events/fall", lambda m: add("A/fall", m.payload.to_string())),
                s.declare_subscriber("posed/A/pose", lambda m: add("A/pose", m.payload.to_string())),
                s.declare_subscriber("posed/B/**", lambda m: add("B/raw", (str(m.key_expr), m.payload.to_string()))),
                s.liveliness().declare_subscriber("posed/*/alive/**", lambda m: add("alive", str(m.key_expr)),
                                                  history=True)]
        station.on_event("A", lambda robot, e: add("A/event", (robot, e.id, e.state)))
        station.on_event("B", lambda robot, e: add("B/event", (robot, e.id, e.state)))
        station.on_status("B", lambda robot, st: add("B/status", robot))
        b.start()
        a.start()
        wait_for(lambda: station.robots() == ["A", "B"], 180, "robots A and B up, seen through the router", a)
        wait_for(lambda: got("A/event"), 180, "A's fall event at the caregiver", a)
        assert {robot for robot, _, _ in got("A/event")} == {"A"}
        assert got("A/pose"), "no pose of A at the caregiver"
        wait_for(lambda: got("B/status"), 30, "B's status at the caregiver", b)
        assert got("B/event") == [], "robot B (an everyday recording) had a fall event"

        # robot A compromised: its certificate replays A's real fall and a pose of A on robot B's keys
        parties.append(_party(tmp_path, certs / "robots" / "A", "posed-daemon", rep, name="robot-A-certificate"))
        impostor = parties[-1].session
        fall, pose = _as_b(got("A/fall")[-1]), _as_b(got("A/pose")[-1])
        token = impostor.liveliness().declare_token("posed/B/alive/impostor.1.host")
        for _ in range(10):
            impostor.put("posed/B/events/fall", fall)
            impostor.put("posed/B/pose", pose)
            time.sleep(0.1)
        # the control: the same session's put on A's own keys reaches the caregiver (later than the forged ones)
        def control() -> bool:
            impostor.put("posed/A/pose", "control")
            time.sleep(0.2)
            return "control" in got("A/pose")

        wait_for(control, 20, "the control put on posed/A/pose")
        n = len(got("B/status"))
        wait_for(lambda: len(got("B/status")) >= n + 4, 20, "four more statuses of B (B still heard)", b)
        forged = [(k, p) for k, p in got("B/raw") if p in (fall, pose)]
        assert forged == [], f"A's certificate spoke for robot B: {[(k, p[:60]) for k, p in forged]}"
        assert [k for k, _ in got("B/raw") if k == "posed/B/events/fall"] == []
        assert got("B/event") == [], "the caregiver read a fall of robot B"
        assert "posed/B/alive/impostor.1.host" not in got("alive"), "A's certificate showed B's liveliness token"
        assert a.proc.poll() is None and b.proc.poll() is None
        token.undeclare()
        del subs
    finally:
        for p in parties:
            p.close()
        for d in (b, a):
            d.stop()
        rt.close()


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_two_daemons_with_one_robot_id_find_each_other_with_its_own_certificate(tmp_path, shared_data):
    """Two real ``posed run`` given robot id A on one machine, each with A's generated posed-daemon.json5 and A's
    own certificate (CN posed-daemon.A), the second connected to the first's TLS listener: each says
    ``robot_id_in_use`` naming the other. Fails if the generated subject "daemons" does not admit the robot's own
    CN (the shipped one admits only posed-daemon: their tokens were denied and nothing was said)."""
    from tests.daemon.robots_util import Daemon as Robot
    from tests.daemon.robots_util import stop_all

    certs = fleet_certs(tmp_path / "certs", ("A",))
    r = make_acl(tmp_path / "acl", "--robot", "A")
    assert r.returncode == 0, r.stderr
    cfg = _render(tmp_path / "acl" / "A" / "posed-daemon.json5", tmp_path / "posed-daemon-A.json5",
                  certs / "robots" / "A")
    ports = free_port(), free_port()
    eps = [f"tls/127.0.0.1:{p}" for p in ports]
    tls = ("--set", f"zenoh.config_file={cfg}")
    first = Robot(tmp_path, "first", "A", ports[0], shared_data, extra=(*tls, "--set", f"zenoh.listen=[{eps[0]}]"))
    second = None
    try:
        first.wait_log("zenoh_open", 90)
        second = Robot(tmp_path, "second", "A", ports[1], shared_data,
                       extra=(*tls, "--set", f"zenoh.listen=[{eps[1]}]", "--set", f"zenoh.connect=[{eps[0]}]"))
        said_first, said_second = first.wait_log("robot_id_in_use", 60), second.wait_log("robot_id_in_use", 60)
        assert any(f"pid {second.pid} on host" in o for o in said_first[0]["other_daemons"]), said_first
        assert any(f"pid {first.pid} on host" in o for o in said_second[0]["other_daemons"]), said_second
    finally:
        stop_all(*(d for d in (second, first) if d is not None))
