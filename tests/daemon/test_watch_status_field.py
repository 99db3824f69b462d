"""The status's ``watch`` (daemon.outbox.watch_hooks.WatchLoss.state) and its readers' fallback for a status
without it (an older posed, one still starting): client.Status.not_watching and the web page (viz.web.hub) judge
such a status with the daemon's own rule, so for every state and camera the daemon's ``watch.reason`` and the
client's fallback say the same; with ``watch`` the readers take the daemon's word and its ``since_unix``."""

from __future__ import annotations

import itertools

from posed.client import Status
from posed.daemon.outbox.watch_hooks import WatchLoss
from posed.viz.web.hub import Hub

STATES = ("starting", "running", "blind", "waiting_for_camera", "degraded", "escalated", "stopping")
CAMERAS = ({}, {"state": "open"}, {"state": "lost", "error": "unplugged"}, {"state": "ended"}, {"state": "opening"})


def test_the_fallback_says_what_the_daemon_says():
    for state, camera in itertools.product(STATES, CAMERAS):
        status = {"state": state, "camera": camera, "blind": {"reason": "no frame for 3.0 s", "fix": "-"}}
        loss = WatchLoss("r", 60.0)
        loss.update({"state": "running", "camera": {"state": "open"}}, 0.0, 1000.0)
        loss.update(status, 1.0, 1001.0)
        watch = loss.state()
        old = Status.from_json(dict(status))                  # without watch: the client's own rule
        new = Status.from_json({**status, "watch": watch})
        if state in ("starting", "stopping"):                 # undecided: the judgement before stands
            assert watch["watching"] and watch["since_unix"] == 1000.0
            continue
        assert new.not_watching == old.not_watching == watch["reason"], (status, watch)
        assert watch["since_unix"] == (1000.0 if watch["watching"] else 1001.0)


def test_since_stays_while_not_watching_and_no_judgement_before_the_first_decided_status():
    loss = WatchLoss("r", 60.0)
    loss.update({"state": "starting", "camera": {}}, 0.0, 1000.0)
    assert loss.state() is None
    ended = {"state": "running", "camera": {"state": "ended", "error": "end of file"}}
    loss.update(ended, 1.0, 1001.0)
    loss.update({"state": "blind", "camera": {"state": "open"}, "blind": {"reason": "dark"}}, 2.0, 1002.0)
    assert loss.state() == {"watching": False, "since_unix": 1001.0, "reason": "blind", "detail": "dark"}
    loss.update({"state": "running", "camera": {"state": "open"}}, 3.0, 1003.0)
    assert loss.state() == {"watching": True, "since_unix": 1003.0, "reason": None, "detail": None}


def test_the_page_takes_the_daemon_s_since():
    hub = Hub("r", wall=lambda: 5000.0)
    watch = {"watching": False, "since_unix": 1234.5, "reason": "camera ended", "detail": None}
    hub.on_status("r", Status.from_json({"state": "running", "camera": {"state": "ended"}, "watch": watch}))
    nw = hub.snapshot()["status"]["not_watching"]
    assert nw == {"reason": "the camera stopped (the recording ended)", "since_unix": 1234.5, "since_known": True}
    hub = Hub("r", wall=lambda: 5000.0)                      # an older posed: since this view saw it
    hub.on_status("r", Status.from_json({"state": "running", "camera": {"state": "ended"}}))
    nw = hub.snapshot()["status"]["not_watching"]
    assert nw["since_unix"] == 5000.0 and nw["since_known"] is False
