"""Two real ``posed run`` daemons on one machine (two configs, state dirs, robot ids, Zenoh ports), replaying
a real fall (URFD landmarks) and publishing on real Zenoh on 127.0.0.1 (multicast scouting off).

* apart, they share nothing: a kill -9 of one whole daemon, and the orphan clean-up of the next start, leave
  the other's shared memory and processes alone, and the killed one's state dir is free again at once (guard);
* one state dir given to both is refused (exit 78, the holder and the fix named), not shared silently;
* one listen port given to both is refused (exit 78, naming the robot that holds it and the fix), whether the
  second one starts later (``posed run``'s check) or both start at the same moment (the publisher's).
"""

from __future__ import annotations

from pathlib import Path

from posed.client import PosedClient
from posed.daemon.bus.listen_check import ListenPortTaken
from tests.daemon.bus_seen import Seen
from tests.daemon.robots_util import Daemon, stop_all, wait
from tests.daemon.zenoh_util import free_port

SHM = Path("/dev/shm")


def _segments(pid: int) -> set[str]:
    return {p.name for p in SHM.glob(f"posed-{pid}-*")}


def _statuses(endpoint: str, robot: str) -> tuple[PosedClient, Seen]:
    posed = PosedClient.connect(endpoint, wait_s=30)
    seen = Seen()
    posed.on_status(robot, seen.status)
    return posed, seen


def test_two_daemons_apart_and_a_kill_of_one_leaves_the_other_alone(tmp_path, shared_data):
    """Guard. A and B run side by side; A's whole process group is killed -9 (its segments and semaphore list
    stay in /dev/shm); C then starts on A's state dir (free again: the lock went with A) and removes what A left,
    while B's segments and processes stay and B keeps publishing."""
    a = Daemon(tmp_path, "a", "robA", free_port(), shared_data)
    b = Daemon(tmp_path, "b", "robB", free_port(), shared_data)
    c = None
    try:
        for d in (a, b):
            d.wait_log("zenoh_open", 90)
        wait(lambda: _segments(a.pid) and _segments(b.pid), 30, "both daemons' shared memory")
        b_segments = _segments(b.pid)
        assert not (_segments(a.pid) & b_segments)
        a.kill_group()
        left = _segments(a.pid)
        assert left, "a kill -9 of the whole group leaves the segments (what the next start removes)"
        c = Daemon(tmp_path, "c", "robC", free_port(), shared_data, state=a.state)
        c.wait_log("zenoh_open", 90)
        assert c.proc.poll() is None
        removed = c.events("removed_stale_shared_memory")
        assert removed and set(left) <= set(removed[0]["segments"]), removed
        assert _segments(b.pid) == b_segments, "the other daemon's shared memory was touched"
        assert b.proc.poll() is None
        posed, seen = _statuses(b.endpoint, "robB")
        with posed:
            seen.wait(lambda s: any(st.state == "running" for st in s.statuses), 30, "robB still running")
    finally:
        stop_all(*(d for d in (a, b, c) if d is not None))
    assert not _segments(b.pid) and not _segments(c.pid)


def test_a_second_daemon_on_the_same_state_dir_is_refused(tmp_path, shared_data):
    """Fails without the state dir lock: the second daemon ran and both wrote one journal (robA's and robB's
    fall events in one events.sqlite3, each daemon taking the other's back at its next start)."""
    shared = tmp_path / "shared-state"
    a = Daemon(tmp_path, "a", "robA", free_port(), shared_data, state=shared)
    b = None
    try:
        a.wait_log("zenoh_open", 90)
        b = Daemon(tmp_path, "b", "robB", free_port(), shared_data, state=shared)
        code = wait(lambda: b.proc.poll(), 60, "the second daemon to stop")
        err = b.err.read_text()
        assert code == 78, err
        assert f"pipeline.state_dir: {shared} is in use by another posed daemon (pid {a.pid}" in err, err
        assert "robot_id=robA" in err and "give each daemon its own pipeline.state_dir" in err, err
        assert "nothing was started" in err
        wait(lambda: a.journal(), 60, "robA's first fall event in the journal", a)
        assert {row[0] for row in a.journal()} == {"robA"}
        assert a.proc.poll() is None
    finally:
        stop_all(*(d for d in (a, b) if d is not None))
    again = Daemon(tmp_path, "again", "robB", free_port(), shared_data, state=shared)
    try:                                    # the lock goes with the daemon that held it
        again.wait_log("zenoh_open", 90)
    finally:
        stop_all(again)


def test_a_second_daemon_on_a_taken_listen_port_is_refused(tmp_path, shared_data):
    """Fails without the fix: the second daemon ran on without a bus (one `zenoh_unavailable` line a minute),
    its poses and fall events heard by nobody. Started later, `posed run` refuses it before any stage; started at
    the same moment (both find the port free), the publisher of the one that comes second stops it."""
    port = free_port()
    a = Daemon(tmp_path, "a", "robA", port, shared_data)
    b = None
    try:
        a.wait_log("zenoh_open", 90)
        b = Daemon(tmp_path, "b", "robB", port, shared_data)
        assert wait(lambda: b.proc.poll(), 60, "the second daemon to stop") == 78, b.err.read_text()
        err = b.err.read_text()
        assert f"zenoh.listen: tcp/127.0.0.1:{port} is already in use by the posed daemon of robot robA" in err, err
        assert "needs a port of its own" in err and f"zenoh.connect=[tcp/127.0.0.1:{port}]" in err, err
        assert "nothing was started" in err and not b.events("zenoh_unavailable")
    finally:
        stop_all(*(d for d in (a, b) if d is not None))

    port = free_port()
    both = [Daemon(tmp_path, f"at-once-{r}", r, port, shared_data) for r in ("robC", "robD")]
    try:
        loser = wait(lambda: [d for d in both if d.proc.poll() is not None], 90, "one of the two to stop")
        assert len(loser) == 1 and loser[0].proc.returncode == 78, [d.err.read_text() for d in both]
        winner = next(d for d in both if d is not loser[0])
        err = loser[0].err.read_text()
        assert f"tcp/127.0.0.1:{port} is already in use by the posed daemon of robot {winner.robot}" in err, err
        # the publisher stopped it (both found the port free at start): its fix is the port's, not the config file's
        assert "fix zenoh.config_file" not in err, err
        if err.startswith("posed: publisher:"):
            assert f"fix: {ListenPortTaken.fix}" in err, err
        posed, seen = _statuses(winner.endpoint, winner.robot)
        with posed:
            seen.wait(lambda s: any(st.state == "running" for st in s.statuses), 30, "the other one running")
        assert winner.proc.poll() is None
    finally:
        stop_all(*both)
