"""The page's "not watching" verdict (viz.web.hub.not_watching) is the daemon's own rule for
hooks.on_watch_lost (daemon.outbox.watch_hooks.why_not_watching): the same statuses are "not watching", the
same are undecided, the same are watching. viz may not import the daemon, so the rule is written twice."""

from __future__ import annotations

import itertools

from posed.daemon.outbox.watch_hooks import why_not_watching
from posed.viz.web.hub import not_watching

STATES = ("starting", "running", "blind", "waiting_for_camera", "degraded", "escalated", "stopping", "paused")
CAMERAS = (None, {}, {"state": "open"}, {"state": "lost", "error": "unplugged"}, {"state": "ended"},
           {"state": "reconnecting"})


def test_the_page_judges_watching_as_the_daemon_does():
    for state, camera in itertools.product(STATES, CAMERAS):
        status = {"state": state, "camera": camera, "blind": {"reason": "no frame for 3.0 s"}}
        daemon, page = why_not_watching(dict(status)), not_watching(status)
        assert (daemon is None) == (page is None), (status, daemon, page)
        assert (daemon == "") == (page == ""), (status, daemon, page)
