"""``posed pause DURATION [--by NAME] [--robot R]``: ask the running daemon to stop watching for a while (privacy:
a bath, a visitor); ``0`` resumes (``posed resume``, :mod:`posed.commands.resume`, is the same with 0).

A Zenoh query on ``posed/ROBOT/privacy/pause?for=SECONDS;by=NAME`` (docs/daemon.md, "Pausing for privacy"),
through the daemon's endpoint and robot id from the config (as ``posed events ack``). The answer is printed with
its end in the robot's time zone (the status's ``time_zone``, else this machine's): ``paused until 15:42 CET, by
voice``. DURATION: seconds (``900``, ``90.5``) or ``30s``, ``15m``, ``1h``, ``1h30m``; ``0`` resumes.

Exit status: 0 answered (paused, or resumed); 1 the daemon refused (the reason and the fix on stderr: pausing not
allowed, a fall not acknowledged); 2 a bad argument; 69 no daemon answered (EX_UNAVAILABLE: none running, a
wrong endpoint or robot id, or the bus's access control keeps this program away).
"""

from __future__ import annotations

import argparse
import sys

from posed.commands import add_config_args, config_from_args
from posed.daemon.bus.pause_query import MAX_BY_CHARS

EX_UNAVAILABLE = 69


def register(sub: argparse._SubParsersAction) -> None:
    pause = sub.add_parser(
        "pause", help="stop watching for a while, for privacy (the daemon resumes by itself)",
        description="Asks the running daemon (posed/ROBOT/privacy/pause) to look at no frame for DURATION: the "
                    "camera is closed, no pose is published, and the status says paused. A new pause replaces "
                    "the running one; one longer than the robot's privacy.max_pause_s is cut to it.")
    pause.add_argument("duration", metavar="DURATION",
                       help="how long: seconds (900, 90.5) or 30s, 15m, 1h, 1h30m; 0 resumes now")
    add_common_args(pause)
    pause.set_defaults(func=run_pause)


def add_common_args(parser: argparse.ArgumentParser) -> None:
    """The options ``posed pause`` and ``posed resume`` share (the config, --by, --robot, --connect, --wait)."""
    add_config_args(parser, source=False, example="robot_id=kitchen")
    parser.add_argument("--by", metavar="NAME", default=None,
                        help=f"who asks, shown in the status and the report (free text, at most {MAX_BY_CHARS} "
                             "characters; default: your user name and this host, USER@HOST; --by '' sends none)")
    parser.add_argument("--robot", metavar="ROBOT", help="robot id (default: the config's robot_id)")
    parser.add_argument("--connect", metavar="ENDPOINT",
                        help="the daemon's Zenoh endpoint (default: from the config's zenoh.listen)")
    parser.add_argument("--wait", type=float, default=5.0, metavar="S",
                        help="keep trying to connect, then wait for the answer, this long (default 5 s)")


def run_pause(args: argparse.Namespace) -> int:
    from posed.daemon.bus.pause_query import BadPause, parse_duration

    try:
        seconds = parse_duration(args.duration)
    except BadPause as exc:
        print(f"posed pause: {exc}", file=sys.stderr)
        return 2
    return ask(args, "posed pause", seconds)


def _by(args: argparse.Namespace, who: str) -> str | None:
    from posed.client.api import PARAMETER_CHARS
    from posed.commands.events import default_by

    if args.by is None:
        by = default_by()[:MAX_BY_CHARS]
    else:
        by = args.by.strip()
    if len(by) > MAX_BY_CHARS or not by.isprintable() or any(c in by for c in PARAMETER_CHARS):
        raise ValueError(f"{who}: --by must be at most {MAX_BY_CHARS} printable characters without "
                         f"{' '.join(PARAMETER_CHARS)}")
    return by or None


def ask(args: argparse.Namespace, who: str, seconds: float) -> int:
    from posed.client import PosedClient, PosedClientError
    from posed.client.api import NoAnswerError
    from posed.commands._bus import open_client
    from posed.daemon.bus.session import daemon_endpoints

    cfg = config_from_args(args)
    try:
        by = _by(args, who)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    robot = args.robot or cfg.robot_id
    endpoints = (args.connect,) if args.connect else daemon_endpoints(cfg.zenoh)
    session = open_client(cfg, endpoints, args.wait, who)
    if session is None:
        return EX_UNAVAILABLE
    with session:
        client = PosedClient(session)
        try:
            if seconds > 0:
                state = client.pause(seconds, by, robot=robot, timeout=args.wait)
            else:
                state = client.resume(by, robot=robot, timeout=args.wait)
        except NoAnswerError as exc:
            print(f"{who}: {exc}", file=sys.stderr)
            return EX_UNAVAILABLE
        except PosedClientError as exc:
            print(f"{who}: refused: {exc}", file=sys.stderr)
            return 1
        zone = _robot_zone(client, robot)
    print(f"{who}: robot {robot}: {answer_text(state, zone, seconds)}", flush=True)
    return 0


def answer_text(state, zone, asked_s: float) -> str:
    """``paused until 15:42 CET, by voice`` (+ ``(cut to the robot's longest pause, 60 min)``), or ``watching``."""
    if not state.paused:
        return "watching (not paused)" if asked_s > 0 else "resumed: watching"
    from posed.daemon.timeparse import until_text

    until = until_text(state.until_unix, zone)
    text = f"paused until {until}" + (f", by {state.by}" if state.by else "")
    if state.clamped:
        text += f" (cut to the robot's longest pause, privacy.max_pause_s = {state.max_pause_s:g} s)"
    return text


def _robot_zone(client, robot: str):
    """The robot's time zone (its status's ``time_zone``), else this machine's (daemon.timeparse.local_zone)."""
    from posed.daemon.timeparse import local_zone

    try:
        status = client.state(robot, timeout=2.0).status
        name = status.raw.get("time_zone") if status is not None else None
        return local_zone(name) if name else local_zone()
    except Exception:               # an older daemon, no status yet, an unknown zone: this machine's
        return local_zone()
