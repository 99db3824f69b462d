"""The pipeline's stage processes: which run, in what order, and the mailboxes between them.

capture -> landmarks -> fitting -> publisher; a ``*.landmarks.jsonl`` source skips the landmark stage (its
capture stage reads the recorded landmarks). Entry points are ``module:function`` strings, resolved in the
spawned process.
"""

from __future__ import annotations

from dataclasses import dataclass

from posed import hal
from posed.daemon.config import Config


@dataclass(frozen=True)
class StageSpec:
    """One stage of the pipeline: its name, entry point and the mailboxes it reads and writes."""

    name: str
    entry: str
    input: str | None = None
    output: str | None = None
    uses_ring: bool = False


def is_landmark_recording(cfg: Config) -> bool:
    return cfg.source.type == "file" and hal.is_landmark_recording(cfg.source.path)


def default_plan(cfg: Config) -> tuple[StageSpec, ...]:
    """capture -> landmarks -> fitting -> publisher (-> web, when ``web.enabled``: the live page, a receiver of
    the publisher's topics); a ``*.landmarks.jsonl`` source skips the landmark stage."""
    fit = StageSpec("fitting", "posed.daemon.stages.fit:run", "landmarks", "fits")
    pub = StageSpec("publisher", "posed.daemon.stages.publish:run", "fits", None)
    web = (StageSpec("web", "posed.daemon.stages.web:run"),) if cfg.web.enabled else ()
    if is_landmark_recording(cfg):
        return (StageSpec("capture", "posed.daemon.stages.capture:run_recording", None, "landmarks"), fit, pub, *web)
    return (StageSpec("capture", "posed.daemon.stages.capture:run", None, "frames", uses_ring=True),
            StageSpec("landmarks", "posed.daemon.stages.landmark:run", "frames", "landmarks", uses_ring=True),
            fit, pub, *web)
