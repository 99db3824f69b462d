"""``python -m tests.daemon.supervise_plan STATUS_FILE [--fatal|--publisher] [--set KEY=VALUE ...]``: the real
Supervisor running the test plan of plan_stages.py; each status object is appended to STATUS_FILE as a JSON
line so that a test can follow pids, restarts and frame counts."""

from __future__ import annotations

import argparse
import json
import sys

from posed.daemon import logs
from posed.daemon.config import load_config
from posed.daemon.supervisor import Supervisor
from tests.daemon.plan_stages import FATAL_PLAN, PLAN, PUBLISHER_PLAN, WEB_PLAN


class RecordingSupervisor(Supervisor):
    def __init__(self, *a, status_file: str, **kw) -> None:
        super().__init__(*a, **kw)
        self._status_file = status_file

    def _publish_status(self, now: float) -> None:
        super()._publish_status(now)
        with open(self._status_file, "a") as fh:
            fh.write(json.dumps(self.last_status) + "\n")


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("status_file")
    parser.add_argument("--fatal", action="store_true")
    parser.add_argument("--publisher", action="store_true", help="scripted fall fits -> the real publisher")
    parser.add_argument("--web", action="store_true", help="scripted fits and the web stage, no publisher")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args()
    cfg = load_config(None, overrides=args.overrides)
    logs.configure("info", "json")
    plan = FATAL_PLAN if args.fatal else PUBLISHER_PLAN if args.publisher else WEB_PLAN if args.web else PLAN
    sup = RecordingSupervisor(cfg, plan, status_file=args.status_file)
    return sup.run()


if __name__ == "__main__":
    sys.exit(main())
