"""The client against a real daemon replaying a real fall (urfd_02) through a router on 127.0.0.1: the
10-line example of docs/client.md run as written, subscriptions decoded into FitResult / FallEvent / Status,
state and history queries, acknowledgements, liveliness, and what happens to a message that is not one."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from posed.client import Alive, PosedClient, PosedClientError, Status
from posed.falls import FallEvent
from posed.fitting import FitResult
from tests.daemon.zenoh_util import free_port, router
from tests.interop.daemons import ROOT, URFD, Daemon, fall_overrides, wait_for

DOC = ROOT / "docs" / "client.md"


def doc_example(doc: Path = DOC) -> str:
    text = doc.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "docs/client.md has no python example"
    return blocks[0]


@pytest.fixture(scope="module")
def fleet_of_one(tmp_path_factory, shared_data):
    """A router and one daemon looping the fall clip, with at least one fall event published."""
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    d = Daemon(tmp_path_factory.mktemp("client"), "docs1", shared_data / URFD / "urfd_02_fall.landmarks.jsonl",
               rep, *fall_overrides(shared_data), "source.loop=true", "source.realtime=true",
               "pipeline.status_period_s=0.5").start()
    try:
        with PosedClient.connect(rep, wait_s=30) as c:
            events: list = []
            c.on_event("docs1", lambda robot, e: events.append(e))
            wait_for(lambda: events, 180, "a fall event", d)
        yield rep, d
    finally:
        d.stop()
        r.close()


def _open_messages(rep) -> dict[tuple[str, str], float | None]:
    with PosedClient.connect(rep) as c:
        return {(e.event.id, e.event.state): e.acked_at for e in c.history("docs1", limit=500)}


def test_the_documented_example_runs(fleet_of_one):
    """As written it lists and acknowledges nothing; given one message (ROBOT/ID/STATE, as it prints them) it
    acknowledges that one and no other."""
    rep, d = fleet_of_one
    code = doc_example().replace("tcp/127.0.0.1:7447", rep)
    assert len(code.strip().splitlines()) <= 11
    # the looping replay's falls: at least two messages open, so that one can stay open
    wait_for(lambda: sum(a is None for a in _open_messages(rep).values()) >= 2, 180, "two open fall messages", d)
    before = _open_messages(rep)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    text = out.stdout                      # the callbacks print from Zenoh's threads, after the listing
    assert text.startswith("robots up: ['docs1']\n")
    assert re.search(r"docs1 \d+ (-?\d+\.\d+|None)\n", text), text[:500]    # the knee by its plain name
    listed = re.findall(r"^docs1/(\w+)/(\w+) (open|acknowledged)$", text, re.M)
    assert any(s == "open" for _, _, s in listed), text[:1000]
    after = _open_messages(rep)
    assert all(after[k] is None for k, a in before.items() if a is None)   # nothing acknowledged unasked
    event_id, state = next((i, s) for i, s, o in listed if o == "open" and before.get((i, s), 0) is None)
    out = subprocess.run([sys.executable, "-c", code, f"docs1/{event_id}/{state}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert f"acknowledged docs1 {event_id} {state}" in out.stdout
    after = _open_messages(rep)
    assert after[(event_id, state)] is not None
    others = [k for k, a in before.items() if a is None and k != (event_id, state)]
    assert others and all(after[k] is None for k in others)      # the other open messages stay open


def test_the_plain_zenoh_example_of_formats_md_runs(fleet_of_one):
    rep, d = fleet_of_one
    code = doc_example(ROOT / "docs" / "formats.md").replace("tcp/127.0.0.1:7447", rep)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert any(re.fullmatch(r"docs1 (falling|on_floor|alarm|recovered) \d+\.\d+ (None|\d+\.\d+)", x)
               for x in lines), lines
    assert re.fullmatch(r"\d+\.\d+", lines[-1]), lines


def test_posed_watch_reads_through_the_client(fleet_of_one):
    rep, d = fleet_of_one
    out = subprocess.run([sys.executable, "-m", "posed.cli", "watch", "--connect", rep, "--seconds", "4"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "posed watch: robot docs1 up" in out.stdout
    assert re.search(r" fps .*seq \d+ +\[(running|degraded), recording open", out.stdout), out.stdout


def test_subscriptions_queries_and_liveliness(fleet_of_one):
    rep, d = fleet_of_one
    got: dict[str, list] = {"pose": [], "status": [], "alive": [], "errors": []}
    lock = threading.Lock()

    def keep(kind):
        def f(*args):
            with lock:
                got[kind].append(args)
        return f

    with PosedClient.connect(rep) as c:
        c.on_pose("*", keep("pose"), on_error=keep("errors"))
        c.on_status("docs1", keep("status"))
        c.on_alive(lambda a: keep("alive")(a))
        wait_for(lambda: len(got["pose"]) >= 5 and got["status"] and got["alive"], 30, "poses, status, alive")
        robot, fit = got["pose"][-1]
        assert robot == "docs1" and isinstance(fit, FitResult) and fit.extra["format"] == "posed.pose"
        assert isinstance(fit.extra["time_unix"], float) and fit.extra["image_size"] == [640, 480]
        assert isinstance(got["status"][-1][1], Status) and got["status"][-1][1].state in ("running", "degraded")
        assert got["alive"][0][0] == Alive("docs1", True)
        assert c.robots() == ["docs1"]

        state = c.state("docs1")
        assert state.robot == "docs1" and isinstance(state.pose, FitResult) and state.status.robot == "docs1"

        history = c.history("*", limit=50)
        assert history and all(isinstance(h.event, FallEvent) and h.robot == "docs1" for h in history)
        assert all(h.event.extra["time_unix"] > 1.6e9 for h in history)
        open_ = [h for h in history if h.acked_at is None]
        if open_:
            h = open_[0]
            assert c.ack("docs1", h.event.id, h.event.state, by="test", confirm_s=10.0) is True

        # a message that is not one: counted and reported, never handed to the callback
        c.session.put("posed/docs1/pose", "{not json")
        c.session.put("posed/docs1/pose", "[1, 2]")
        wait_for(lambda: len(got["errors"]) >= 2, 10, "the decode errors")
        assert c.decode_errors >= 2 and all(k == "posed/docs1/pose" for k, _ in got["errors"])

        with pytest.raises(PosedClientError, match="no answer"):
            c.state("nobody", timeout=1.0)
        with pytest.raises(ValueError, match="robot"):
            c.on_pose("a/b", print)


def test_connect_to_nothing_says_what_to_check():
    with pytest.raises(PosedClientError, match="is the daemon"):
        PosedClient.connect(f"tcp/127.0.0.1:{free_port()}", wait_s=0.5)


def test_a_robot_going_away_is_seen(tmp_path, shared_data):
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    try:
        d = Daemon(tmp_path, "gone1", shared_data / URFD / "urfd_02_fall.landmarks.jsonl", rep,
                   "source.loop=true", "source.realtime=true").start()
        changes: list[Alive] = []
        with PosedClient.connect(rep, wait_s=30) as c:
            c.on_alive(changes.append)
            wait_for(lambda: Alive("gone1", True) in changes, 120, "gone1 up", d)
            d.stop()
            wait_for(lambda: Alive("gone1", False) in changes, 15, "gone1 down")
            time.sleep(0.2)
            assert c.robots(timeout=1.0) == []
    finally:
        d.stop()
        r.close()
