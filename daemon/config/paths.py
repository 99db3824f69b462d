"""Where the daemon keeps fall events and joint-angle history (the state dir)."""

from __future__ import annotations

import os
from pathlib import Path

from daemon.config.sections import PipelineConfig

EVENTS_FILE = "events.sqlite3"
HISTORY_FILE = "history.sqlite3"


def state_dir(pipeline: PipelineConfig | None = None, environ: dict | None = None) -> Path:
    """``pipeline.state_dir`` if set; else ``$STATE_DIRECTORY`` (systemd's StateDirectory=, first entry);
    else ``$XDG_STATE_HOME/posed``; else ``~/.local/state/posed``."""
    env = os.environ if environ is None else environ
    if pipeline is not None and pipeline.state_dir:
        return Path(pipeline.state_dir).expanduser()
    if env.get("STATE_DIRECTORY"):
        return Path(env["STATE_DIRECTORY"].split(":")[0])
    if env.get("XDG_STATE_HOME"):
        return Path(env["XDG_STATE_HOME"]) / "posed"
    return Path(env.get("HOME") or Path.home()) / ".local" / "state" / "posed"


def events_path(pipeline: PipelineConfig | None = None) -> Path:
    return state_dir(pipeline) / EVENTS_FILE


def history_path(pipeline: PipelineConfig | None = None) -> Path:
    return state_dir(pipeline) / HISTORY_FILE
