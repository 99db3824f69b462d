"""Several robots on one Zenoh network: real ``posed run`` daemons replaying a real fall (URFD landmarks), the
second one a peer connected to the first (as robots of a care home on one bus), real Zenoh on 127.0.0.1 with
multicast scouting off, read by the real client and the real ``posed watch``.

* Robots kept apart (guards, except ``posed watch``): a client reaching one daemon sees both robots, their own
  fall events, each robot's history only its own; an acknowledgement addressed to robot A of an event of robot
  B does nothing anywhere, the one addressed to B acknowledges it in B's journal only. ``posed watch`` of every
  robot gives each robot its own line (it mixed both robots' poses and statuses into one). ``posed events ack
  --robot B`` on robot A's machine is confirmed through B's history, not A's journal (it exited 1 although B
  acknowledged).
* Two daemons with one robot id on one network: each logs ``robot_id_in_use`` naming the other, its status
  says so (``zenoh.robot_id_conflict``, ``client.Status.robot_id_conflict``) and ``posed watch`` prints it; when
  one stops, ``robot_id_conflict_ended``; systemd's STATUS= line says it while it lasts. Each status names the
  landmark models the daemon runs (``models``).
"""

from __future__ import annotations

import subprocess
import sys

from posed.client import PosedClient
from posed.landmarks import installed_models
from tests.daemon.bus_seen import Seen
from tests.daemon.harness import NotifyListener
from tests.daemon.robots_util import ROOT, Daemon, stop_all, wait
from tests.daemon.zenoh_util import free_port


def _watch(endpoint: str, *args: str, seconds: float = 4.0) -> list[str]:
    r = subprocess.run([sys.executable, "-m", "posed.cli", "watch", *args, "--connect", endpoint,
                        "--seconds", str(seconds)], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout.splitlines()


def _ack_cli(daemon: Daemon, event_id: str, *args: str) -> subprocess.CompletedProcess:
    """``posed events ack`` run with ``daemon``'s own config (robot id, state dir with its journal, endpoint)."""
    return subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", event_id, "--by", "test",
                           "--set", f"robot_id={daemon.robot}", "--set", f"pipeline.state_dir={daemon.state}",
                           "--set", f"zenoh.listen=[{daemon.endpoint}]", *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=90)


def test_robots_on_one_bus_are_kept_apart(tmp_path, shared_data):
    a = Daemon(tmp_path, "a", "robA", free_port(), shared_data)
    try:
        a.wait_log("zenoh_open", 90)
        b = Daemon(tmp_path, "b", "robB", free_port(), shared_data, connect=a.port)
        b.wait_log("zenoh_open", 90)
        with PosedClient.connect(a.endpoint, wait_s=30) as posed:        # reaches robB through robA's daemon
            wait(lambda: posed.robots() == ["robA", "robB"], 30, "both robots up")
            seen = Seen()
            posed.on_event("*", seen.event)
            seen.wait(lambda s: {e.robot for e in s.events} >= {"robA", "robB"}, 90, "fall events of both robots")
            with seen.lock:
                assert all(e.robot in ("robA", "robB") for e in seen.events)

            hist_a, hist_b = posed.history("robA", limit=1000), posed.history("robB", limit=1000)
            assert hist_a and {e.event.robot for e in hist_a} == {"robA"}
            assert hist_b and {e.event.robot for e in hist_b} == {"robB"}
            assert {e.event.robot for e in posed.history("*", limit=1000)} == {"robA", "robB"}

            b_event = hist_b[0].event
            assert not posed.ack("robA", b_event.id, b_event.state, by="test", confirm_s=3.0)
            assert [r for r in b.journal() if r[1] == b_event.id and r[2] == b_event.state][0][3] is None
            assert all(r[1] != b_event.id for r in a.journal())
            assert posed.ack("robB", b_event.id, b_event.state, by="test", confirm_s=10.0)
            assert [r for r in b.journal() if r[1] == b_event.id and r[2] == b_event.state][0][3] is not None
            assert b.events("fall_event_acknowledged") and not a.events("fall_event_acknowledged")
            assert not any(r[3] for r in a.journal())

            open_b = [e for e in posed.history("robB", limit=1000) if e.acked_at is None]
            assert open_b, "robB has no unacknowledged message left to acknowledge"
            a_id = next(r[1] for r in a.journal())

        # `posed events ack --robot robB` on robot A's machine (its config, its journal at hand): completed and
        # confirmed through robB's history, not robA's journal (fails without the fix: exit 1, "does not show
        # ... acknowledged" in robA's journal although robB acknowledged it)
        target = open_b[-1].event.id
        r = _ack_cli(a, target, "--robot", "robB", "--wait", "15")
        assert r.returncode == 0, r.stdout + r.stderr
        assert "robot robB acknowledged" in r.stdout and "does not show" not in r.stderr, r.stdout + r.stderr
        assert all(row[3] is not None for row in b.journal() if row[1] == target)
        assert not any(row[3] for row in a.journal()), "robA's journal changed"
        # a prefix of one of robA's ids is not completed from robA's journal and sent to robB as robA's id
        r = _ack_cli(a, a_id[:12], "--robot", "robB", "--wait", "1")
        assert f"sent event {a_id}" not in r.stdout and not any(row[3] for row in a.journal()), r.stdout

        lines = _watch(a.endpoint)
        assert any(line.startswith("robA ") and " fps " in line for line in lines), lines
        assert any(line.startswith("robB ") and " fps " in line for line in lines), lines
        assert not [line for line in lines if " fps " in line and not line.startswith(("robA ", "robB "))], lines
        one = _watch(a.endpoint, "robB", seconds=3.0)       # one robot asked for: its lines, unprefixed
        assert any(" fps " in line for line in one) and not any(line.startswith("robA") for line in one), one
    finally:
        stop_all(*(d for d in (locals().get("b"), a) if d is not None))


def test_two_daemons_with_one_robot_id_on_one_bus_are_said_loudly(tmp_path, shared_data, monkeypatch):
    """Fails without the fix: nothing said; both daemons' poses and events on posed/robX/* as one robot's.
    systemd's STATUS= line of robot A (the real notify protocol, AF_UNIX) says it too, and no longer once the
    other one stopped (fails without it: the line said nothing of it)."""
    listener = NotifyListener(str(tmp_path / "notify.sock"))
    monkeypatch.setenv("NOTIFY_SOCKET", listener.sock.getsockname())
    a = Daemon(tmp_path, "a", "robX", free_port(), shared_data,      # the only one that tells systemd
               env={"TZ": "Asia/Tokyo"})                            # a robot in Tokyo: its status says so
    monkeypatch.delenv("NOTIFY_SOCKET")
    try:
        a.wait_log("zenoh_open", 90)
        b = Daemon(tmp_path, "b", "robX", free_port(), shared_data, connect=a.port, env={"TZ": "Asia/Tokyo"})
        said_a, said_b = a.wait_log("robot_id_in_use", 60), b.wait_log("robot_id_in_use", 60)
        assert said_a[0]["level"] == "error" and "its own robot_id" in said_a[0]["fix"]
        assert any(f"pid {b.pid} on host" in o for o in said_a[0]["other_daemons"]), said_a
        assert any(f"pid {a.pid} on host" in o for o in said_b[0]["other_daemons"]), said_b

        with PosedClient.connect(a.endpoint, wait_s=30) as posed:
            seen = Seen()
            posed.on_status("robX", seen.status)
            seen.wait(lambda s: any(st.robot_id_conflict for st in s.statuses), 30, "the conflict in the status")
            # which landmark models each daemon runs, as `posed --version` says (fails without it: not in the status)
            with seen.lock:
                models = [st.raw.get("models") for st in seen.statuses]
            assert models and all(m == installed_models() for m in models), models[-1:]
            assert "dir" in models[0] and ("converter_version" in models[0] or "error" in models[0]), models[0]
            # the zone the robot's views show times in (posed web takes it: a carer abroad reads home time)
            with seen.lock:
                zones = [st.raw.get("time_zone") for st in seen.statuses]
            assert zones and set(zones) == {"Asia/Tokyo"}, zones
        lines = _watch(a.endpoint, "robX", seconds=3.0)
        loud = [line for line in lines if line.startswith("ROBOT ID IN USE TWICE")]
        # each second's line is from the latest status, of either daemon: each names the other one
        assert loud and all(f"pid {b.pid} on host" in line or f"pid {a.pid} on host" in line
                            for line in loud), "\n".join(lines)

        twice = wait(lambda: [m for m in listener.texts("STATUS=") if "ROBOT ID IN USE TWICE" in m], 30,
                     "STATUS= saying the robot id is in use twice", a)
        assert f"pid {b.pid} on host" in twice[0] and "its own robot_id" in twice[0], twice[0]
        assert twice[0].startswith(("STATUS=running: ", "STATUS=starting: ", "STATUS=degraded: ")), twice[0]

        stop_all(b)
        a.wait_log("robot_id_conflict_ended", 30)
        n = len(listener.messages)
        wait(lambda: [m for _, m in listener.messages[n:] if m.startswith("STATUS=")
                      and "ROBOT ID IN USE TWICE" not in m], 30, "STATUS= without the conflict once B stopped", a)
        assert a.proc.poll() is None
    finally:
        stop_all(*(d for d in (locals().get("b"), a) if d is not None))
        listener.close()
