"""A robot on a real Zenoh bus for the tests of the pause for privacy: its liveliness token, a status every
``STATUS_PERIOD_S`` as the daemon publishes it (docs/formats.md, the contract of posed/ROBOT/privacy/pause):
running, or ``state: paused`` with its ``privacy`` and the daemon's ``watch`` (not watching, reason ``paused``),
and while it watches a pose every 0.1 s (a fitted body, left knee at ``KNEE_DEG``), none while paused (as the
daemon publishes none)."""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import threading
import time
from zoneinfo import ZoneInfo

from posed.fitting import FitResult
from tests.daemon import zenoh_util

STATUS_PERIOD_S = 0.3
KNEE_DEG = 42.0


def pose(seq: int, t_unix: float) -> FitResult:
    """A fitted body (a few joints, the left knee bent ``KNEE_DEG``), captured at ``t_unix``."""
    return FitResult(seq, seq * 0.1, True, joint_angles_deg={"theta_kn_l": KNEE_DEG},
                     joints_3d={"mid_hip": (0.0, 0.0, 0.0), "left_hip": (0.1, 0.0, 0.0),
                                "left_knee": (0.12, 0.45, 0.0), "right_hip": (-0.1, 0.0, 0.0)},
                     extra={"time_unix": t_unix})


class Robot:
    """A robot on the bus: a client session to the router, its liveliness token, poses while it watches, a status
    every ``STATUS_PERIOD_S``: running, or paused for privacy by ``by`` until ``until_unix`` (``pause``/``resume``)."""

    def __init__(self, robot: str, endpoint: str, zone: str) -> None:
        self.robot, self.zone = robot, zone
        self.pause_of: tuple[str | None, float, float] | None = None      # (by, since, until)
        self.session = zenoh_util.client(endpoint)
        self.token = self.session.liveliness().declare_token(f"posed/{robot}/alive")
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def pause(self, by: str | None, minutes: float) -> float:
        now = time.time()
        self.pause_of = (by, now, now + 60.0 * minutes)
        return self.pause_of[2]

    def resume(self) -> None:
        self.pause_of = None

    def status(self) -> dict:
        now = time.time()
        privacy = {"allow_pause": True, "max_pause_s": 3600.0, "paused": False}
        out = {"format": "posed.status", "version": 1, "robot": self.robot, "state": "running", "time_unix": now,
               "fps": 10.0, "drops": 0, "restarts": 0, "latency_ms": {"p95": 20.0}, "camera": {"state": "open"},
               "events": {"unacknowledged": 0}, "time_zone": self.zone,
               "watch": {"watching": True, "since_unix": now - 60}, "privacy": privacy}
        if self.pause_of is not None:
            by, since, until = self.pause_of
            privacy.update(paused=True, since_unix=since, until_unix=until, remaining_s=until - now, by=by)
            iso = dt.datetime.fromtimestamp(until, ZoneInfo(self.zone)).isoformat(timespec="seconds")
            out.update(state="paused", camera={"state": "paused"}, fps=0.0,
                       watch={"watching": False, "since_unix": since, "reason": "paused",
                              "detail": f"paused for privacy by {by} until {iso}"})
        return out

    def _run(self) -> None:
        seq, next_status = 0, 0.0
        while not self._stop.wait(0.1):
            if self.pause_of is None:
                seq += 1
                self.session.put(f"posed/{self.robot}/pose", json.dumps(pose(seq, time.time()).to_json()))
            if time.monotonic() >= next_status:
                next_status = time.monotonic() + STATUS_PERIOD_S
                self.session.put(f"posed/{self.robot}/status", json.dumps(self.status()))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.token.undeclare()
        self.session.close()


def hhmm(t: float, zone: str) -> str:
    """``t`` (unix s) as the page says a time in ``zone``: HH:MM, with the date before it (YYYY-MM-DD) when that
    is not today there (a pause running past midnight)."""
    at = dt.datetime.fromtimestamp(t, ZoneInfo(zone))
    today = dt.datetime.now(ZoneInfo(zone)).date()
    return at.strftime("%H:%M" if at.date() == today else "%Y-%m-%d %H:%M")


@contextlib.contextmanager
def on_bus():
    """A Zenoh router on a free port of 127.0.0.1 (scouting off) and a list for the test's robots: (endpoint,
    robots); the robots and the router closed after."""
    endpoint = f"tcp/127.0.0.1:{zenoh_util.free_port()}"
    router = zenoh_util.router(endpoint)
    robots: list[Robot] = []
    try:
        yield endpoint, robots
    finally:
        for r in robots:
            r.close()
        router.close()
