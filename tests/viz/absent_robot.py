"""A robot on a real Zenoh bus whose status carries ``presence`` (the absence notice, docs/falls.md) as the daemon
publishes it: tests/viz/paused_robot.py's robot (liveliness token, a status every 0.3 s, poses) with the person
seen 12 min ago (``seen``); or last seen 3 h 25 min ago, absent for 3 h 10 min of watching (15 min posed did not
watch) against a usual 2 h 5 min (``absent``: its poses then say "no person", as the daemon's do with nobody
in view); or seen again now (``back``)."""

from __future__ import annotations

import json
import time

from posed.fitting import FitResult
from tests.viz.paused_robot import STATUS_PERIOD_S, Robot, pose

H, MIN = 3600.0, 60.0
BEGUN = "PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)"
SHOWN = "not seen for 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h 5 min)"
ENDED = "person seen again after 3 h 25 min"


class AbsentRobot(Robot):
    """``presence``: "seen", "absent" or "back" (as the module says), times from when it was made."""

    def __init__(self, robot: str, endpoint: str, zone: str, presence: str = "seen") -> None:
        self.t0 = time.time()
        self.presence = presence
        super().__init__(robot, endpoint, zone)

    def status(self) -> dict:
        out = super().status()
        t0 = self.t0
        seen = {"last_seen_unix": t0 - 12 * MIN, "absent_s": 12 * MIN, "usual_s": 2 * H + 5 * MIN,
                "notice_after_s": 3 * H + 5 * MIN, "days": 14, "learn_days": 7, "learning": False, "absent": False,
                "absent_since_unix": None}
        last = t0 - 3 * H - 25 * MIN
        out["presence"] = {
            "seen": seen,
            "absent": dict(seen, last_seen_unix=last, absent_s=3 * H + 10 * MIN, absent=True, absent_since_unix=t0),
            "back": dict(seen, last_seen_unix=t0, absent_s=0.0, in_view=True),
        }[self.presence]
        return out

    def _run(self) -> None:
        seq, next_status = 0, 0.0
        while not self._stop.wait(0.1):
            seq += 1
            now = time.time()
            fit = FitResult(seq, seq * 0.1, False, reason="no person", extra={"time_unix": now}) \
                if self.presence == "absent" else pose(seq, now)
            self.session.put(f"posed/{self.robot}/pose", json.dumps(fit.to_json()))
            if time.monotonic() >= next_status:
                next_status = time.monotonic() + STATUS_PERIOD_S
                self.session.put(f"posed/{self.robot}/status", json.dumps(self.status()))
