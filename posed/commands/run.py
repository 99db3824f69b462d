"""``posed run [--config FILE] [--source URI]``: the daemon (see daemon/supervisor.py and docs/daemon.md)."""

from __future__ import annotations

import argparse
import os
import sys

from posed.commands import add_config_args, config_from_args, config_problems
from posed.daemon import logs
from posed.daemon.config import EX_CONFIG
from posed.daemon.config.load import ConfigError


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("run", help="run the daemon: camera -> pose -> Zenoh, with watchdog and sd_notify")
    add_config_args(parser)
    parser.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from posed.daemon.bus.listen_check import taken_listen_problems
    from posed.daemon.config.paths import state_dir
    from posed.daemon.preflight import check, hook_program_problems, model_provenance_problems, resolve_source
    from posed.daemon.state_check import StateDirInUse, claim_state_dir, state_dir_problems
    from posed.daemon.supervisor import Supervisor

    try:
        cfg = resolve_source(config_from_args(args), _demo_recording)
    except ConfigError as exc:      # the start-up checks still run on what could be read: every problem at once
        return config_problems(exc, lambda p: f"posed: {p}")
    problems = check(cfg)
    if problems:
        return _refuse(problems)
    unusable = state_dir_problems(state_dir(cfg.pipeline))
    try:        # held until this process exits: a second daemon on the same state dir is refused
        held = claim_state_dir(state_dir(cfg.pipeline))
    except StateDirInUse as exc:
        return _refuse([str(exc)])
    problems = taken_listen_problems(cfg.zenoh)         # another daemon (or zenohd) on this port
    if problems:
        return _refuse(problems)
    logs.configure(cfg.logging.level, cfg.logging.format, robot=cfg.robot_id)
    for p in unusable:     # degraded, not stopped: detection goes on
        logs.get("supervisor").error("state_dir_unusable", problem=p,
                                     note="starting anyway: fall events are kept in memory and the fallback file")
    for p in hook_program_problems(cfg):
        logs.get("supervisor").error("hook_unusable", problem=p,
                                     note="starting anyway: fall events are still published and journalled")
    for p in model_provenance_problems(cfg):
        logs.get("supervisor").error("models_outdated", problem=p,
                                     note="starting anyway on these intact models: posed watches on until they "
                                          "are fetched again")
    try:
        return Supervisor(cfg).run()
    finally:
        if held is not None:
            os.close(held)


def _refuse(problems: list[str]) -> int:
    """Each problem on stderr, and the exit status of a configuration problem (78: systemd does not restart)."""
    for p in problems:
        print(f"posed: {p}", file=sys.stderr)
    print(f"posed: {len(problems)} problem(s); nothing was started", file=sys.stderr)
    return EX_CONFIG


def _demo_recording(path):
    """The generated demo input, made only when the real squat video is missing (offline code: loaded here)."""
    from posed.bench.demo_recording import ensure_demo_recording

    return ensure_demo_recording(path)
