"""``python -m tests.daemon.privacy_live_camera --set source.type=v4l2 --set source.device=DIR/VIDEO.mp4 [--set
KEY=VALUE ...]``: the real daemon (the real Supervisor and every real stage of ``default_plan``) whose source is a
live camera (``source.type: v4l2``) that is a video looped at its own pace behind the v4l2 kind, so the capture
stage treats it as a camera: each ``open`` and ``close`` of it is appended to DIR/camera.log (what a camera's LED
would show). No camera is needed on the test machine."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from posed.daemon import logs
from posed.daemon.config import load_config
from posed.daemon.stages.base import StageRuntime
from posed.daemon.stages.plan import StageSpec, default_plan
from posed.daemon.supervisor import Supervisor

ENTRY = "tests.daemon.privacy_live_camera:capture"


class LoggedCamera:
    """A hal source that says it is a v4l2 camera and writes each open and close to a file."""

    def __init__(self, inner, log: Path) -> None:
        object.__setattr__(self, "_inner", inner)
        object.__setattr__(self, "_log", log)

    def _say(self, what: str) -> None:
        with open(self._log, "a") as fh:
            fh.write(f"{what} {time.time():.3f}\n")

    def open(self) -> None:
        self._say("open")
        self._inner.open()

    def close(self) -> None:
        self._say("close")
        self._inner.close()

    def read(self, timeout_s: float):
        return self._inner.read(timeout_s)

    @property
    def info(self) -> dict:
        return {**dict(self._inner.info), "kind": "v4l2"}

    def __getattr__(self, name: str):
        return getattr(self._inner, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._inner, name, value)


def capture(rt: StageRuntime) -> None:
    """The real capture stage, with the v4l2 kind answered by the logged video (in this spawned process)."""
    from posed import hal
    from posed.daemon.stages import capture as real

    log, video = Path(rt.config.source.device).parent / "camera.log", rt.config.source.device
    hal.register("v4l2", lambda cfg: LoggedCamera(hal.open_source(f"file:{video}?loop=true"), log))
    real.run(rt)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args()
    cfg = load_config(None, overrides=args.overrides)
    logs.configure("info", "json")
    plan = tuple(dataclasses.replace(s, entry=ENTRY) if s.name == "capture" else s for s in default_plan(cfg))
    assert any(isinstance(s, StageSpec) and s.entry == ENTRY for s in plan)
    return Supervisor(cfg, plan).run()


if __name__ == "__main__":
    sys.exit(main())
