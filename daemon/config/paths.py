"""Where things are: the config file every command reads, and the daemon's state dir (fall events and
joint-angle history).

The config file (the same order for every ``posed`` command, docs/config.md):

1. ``--config FILE``;
2. ``$POSED_CONFIG``;
3. ``/etc/posed/config.yaml`` when it exists (the service's, written by deploy/install.sh);
4. the embedded default (built from the code: the text of ``posed config template``, i.e. config.yaml).

The state dir: ``pipeline.state_dir`` if set; else ``$STATE_DIRECTORY`` (systemd's StateDirectory=);
else ``$XDG_STATE_HOME/posed``; else ``~/.local/state/posed``. Commands that only read the state (``posed
events``, ``history``, ``plot``) open the service's ``/var/lib/posed`` instead of that default when the config
in effect is the service's, or when only the service's folder holds the file they read.
"""

from __future__ import annotations

import os
from pathlib import Path

from posed.daemon.config.sections import PipelineConfig

EVENTS_FILE = "events.sqlite3"
HISTORY_FILE = "history.sqlite3"
SYSTEM_CONFIG = Path("/etc/posed/config.yaml")
SERVICE_STATE_DIR = Path("/var/lib/posed")
EMBEDDED = "embedded default"


def config_file(explicit: str | os.PathLike | None = None, environ: dict | None = None,
                system: Path = SYSTEM_CONFIG) -> Path | None:
    """The config file a command reads: ``explicit`` (``--config``), ``$POSED_CONFIG``, ``system`` when it
    exists; None means the embedded default."""
    env = os.environ if environ is None else environ
    if explicit:
        return Path(explicit)
    if env.get("POSED_CONFIG"):
        return Path(env["POSED_CONFIG"])
    if system.is_file():
        return system
    return None


def describe_config_file(path: Path | None) -> str:
    return EMBEDDED if path is None else str(path)


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


def reading_state_dir(pipeline: PipelineConfig | None, config_path: Path | None, filename: str,
                      environ: dict | None = None, service_dir: Path = SERVICE_STATE_DIR,
                      system_config: Path = SYSTEM_CONFIG) -> Path:
    """The state dir a read-only command opens for ``filename``: as :func:`state_dir` when the config or the
    environment names one; the service's folder when the config in effect is the service's
    (``system_config``), or when the user's own folder lacks ``filename`` and the service's folder exists."""
    env = os.environ if environ is None else environ
    own = state_dir(pipeline, env)
    if (pipeline is not None and pipeline.state_dir) or env.get("STATE_DIRECTORY"):
        return own
    if config_path is not None and config_path == system_config and service_dir.is_dir():
        return service_dir
    if not (own / filename).exists() and service_dir.is_dir():
        return service_dir
    return own


def events_path(pipeline: PipelineConfig | None = None) -> Path:
    return state_dir(pipeline) / EVENTS_FILE


def history_path(pipeline: PipelineConfig | None = None) -> Path:
    return state_dir(pipeline) / HISTORY_FILE
