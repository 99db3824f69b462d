"""Run ``posed run`` on a recording to its end behind a Zenoh router on 127.0.0.1 and collect what it published."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

from tests.daemon.test_run_e2e import posed_run
from tests.daemon.zenoh_util import client, free_port, router


def replay_to_end(tmp_path: Path, source: Path, robot: str, keys: tuple[str, ...], *overrides: str,
                  timeout_s: float = 120.0) -> dict[str, list[dict]]:
    """The daemon on ``source`` (unpaced, lossless, stopping at the end) joined to a router, with a subscriber
    on ``posed/ROBOT/KEY`` for each key; the JSON messages received per key, in arrival order. Asserts the
    daemon exited 0 (its stderr in the message otherwise)."""
    rep = f"tcp/127.0.0.1:{free_port()}"
    r = router(rep)
    lock = threading.Lock()
    got: dict[str, list[dict]] = {k: [] for k in keys}

    def keep(into: list[dict]):
        def on(sample) -> None:
            with lock:
                into.append(json.loads(sample.payload.to_string()))
        return on

    try:
        with client(rep) as s:
            subs = [s.declare_subscriber(f"posed/{robot}/{k}", keep(got[k])) for k in keys]
            proc = posed_run(tmp_path, source, f"robot_id={robot}", "source.realtime=false",
                             "pipeline.stop_at_end=true", f"zenoh.listen=[tcp/127.0.0.1:{free_port()}]",
                             f"zenoh.connect=[{rep}]", *overrides)
            try:
                code = proc.wait(timeout=timeout_s)
            finally:
                if proc.poll() is None:
                    proc.kill()
            time.sleep(0.3)
            del subs
        assert code == 0, (tmp_path / "err.log").read_text()
    finally:
        r.close()
    with lock:
        return {k: list(v) for k, v in got.items()}
