"""``posed watch [ROBOT] [--connect ENDPOINT]``: show a running daemon's poses, status and fall events (read with
the :mod:`client` package; ``--json`` prints every raw message instead).

A robot paused for privacy (its status ``state: paused``, ``privacy``; posed/ROBOT/privacy/pause) says so on its
line — ``PAUSED for privacy by voice until 15:42 CET`` in the robot's time zone — instead of "NOT WATCHING": a
pause someone asked for is not a fault.

When the absence notice begins (the status's ``presence``: the person out of view for longer than on any of the
last days at this time, docs/falls.md) a line says so once — ``home: PERSON NOT SEEN FOR 3 h 10 min — longer than
on any of the last 14 days (usually back within 2 h 5 min)`` — and when it ends ``home: person seen again after
3 h 25 min`` (:func:`client.presence_change`)."""

from __future__ import annotations

import argparse
import json
import re
import sys
import time

from posed.commands import add_config_args, config_from_args


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("watch", help="subscribe to a daemon and show its live poses, status and events")
    parser.add_argument("robot", nargs="?", default="*", help="robot id (default: every robot, *)")
    parser.add_argument("--connect", metavar="ENDPOINT",
                        help="the daemon's or a router's Zenoh endpoint (default: where the config's daemon "
                             "listens, zenoh.listen; tcp/127.0.0.1:7447 for the default config)")
    add_config_args(parser, source=False, example="zenoh.listen=[tcp/127.0.0.1:7448]")
    parser.add_argument("--seconds", type=float, default=0.0, help="stop after this long (default: until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="print every message as a JSON line instead")
    parser.add_argument("--wait", type=float, default=10.0, metavar="S",
                        help="keep trying to connect this long (default 10 s)")
    parser.set_defaults(func=_watch)


def open_viewer(endpoint: str, wait_s: float, quiet: bool = False):
    """A client session to ``endpoint``, retried for ``wait_s``; None with a message when it cannot connect."""
    import zenoh

    from posed.daemon.bus.session import build_config
    from posed.daemon.config.sections import ZenohConfig

    cfg = ZenohConfig(mode="client", listen=(), connect=(endpoint,))
    deadline = time.monotonic() + wait_s
    while True:
        try:
            return zenoh.open(build_config(cfg))
        except Exception as exc:
            if time.monotonic() >= deadline:
                if quiet:
                    return None
                print(f"posed watch: cannot connect to {endpoint}: {str(exc).splitlines()[0]}\n"
                      "  is `posed run` running? It listens on tcp/127.0.0.1:7447 by default; give another "
                      "endpoint with --connect", file=sys.stderr)
                return None
            time.sleep(0.25)


# what the summary line says of a status whose watch is "not watching" (posed.commands._viewer.Summary.line)
_NOT_WATCHING = re.compile(r"  NOT WATCHING \(.*?\): a fall would not be detected(?:, since \S+(?: \S+)?)?")
_UNDECIDED = ("starting", "stopping")


def paused_words(status: dict | None) -> str | None:
    """``PAUSED for privacy by voice until 15:42 CET`` while ``status`` (the status message as JSON) says posed
    is paused for privacy (``state: paused``; or ``privacy.paused`` while starting or stopping), the end in the
    robot's time zone (its ``time_zone``; this machine's when not said); None while it is not paused."""
    from posed.daemon.timeparse import until_text

    if not isinstance(status, dict):
        return None
    privacy = status.get("privacy") if isinstance(status.get("privacy"), dict) else {}
    if status.get("state") != "paused" and not (privacy.get("paused") is True
                                                 and status.get("state") in _UNDECIDED):
        return None
    by, until = privacy.get("by"), privacy.get("until_unix")
    text = "PAUSED for privacy" + (f" by {by}" if isinstance(by, str) and by and by.isprintable() else "")
    if isinstance(until, (int, float)) and not isinstance(until, bool):
        text += " until " + until_text(float(until), _zone(status.get("time_zone")))
    return text


def _zone(name):
    """The robot's zone (an IANA name from its status), else this machine's (daemon.timeparse.local_zone)."""
    from posed.daemon.timeparse import local_zone

    try:
        return local_zone(name if isinstance(name, str) else None)
    except ValueError:                 # not a zone this machine knows
        return local_zone()


def _with_pause(summary_class):
    """``summary_class`` (:class:`posed.commands._viewer.Summary`) whose line says a pause for privacy as one, in
    place of "NOT WATCHING"."""

    class PauseAware(summary_class):
        def line(self, elapsed_s: float, period_s: float = 1.0) -> list[str]:
            out = super().line(elapsed_s, period_s)
            said = paused_words(self.status)
            if said and out:
                out[-1] = _NOT_WATCHING.sub("", out[-1]) + "  " + said
            return out

    return PauseAware


class _Decoded:
    """A message the client decoded, handed to the Summary (which reads JSON samples) as its JSON again."""

    def __init__(self, obj) -> None:
        self.payload = self
        self._text = json.dumps(obj)

    def to_string(self) -> str:
        return self._text


class Robots:
    """One :class:`Summary` per robot, so that with several robots on the bus (``posed watch`` of ``*``) each has its
    own line, prefixed with its id: one robot's poses, fps, status and events never mixed into another's. Asked
    for one robot, its lines are as they were, unprefixed."""

    def __init__(self, robot: str, make) -> None:
        import threading

        self.robot, self._make = robot, make
        self._lock = threading.Lock()
        self._by_robot: dict = {}
        self._waiting = make()          # shown while no robot has said anything yet

    def summary(self, robot: str):
        with self._lock:
            if robot not in self._by_robot:
                self._by_robot[robot] = self._make()
            return self._by_robot[robot]

    def lines(self, elapsed_s: float) -> list[str]:
        with self._lock:
            robots = sorted(self._by_robot.items())
        if not robots:
            return self._waiting.line(elapsed_s)
        out = []
        for robot, summary in robots:
            prefix = f"{robot}  " if self.robot == "*" else ""
            out += summary.take_notices()       # "ROBOT: PERSON NOT SEEN FOR ...": named already
            out += [prefix + line for line in summary.line(elapsed_s)]
            conflict = ((summary.status or {}).get("zenoh") or {}).get("robot_id_conflict")
            if conflict:
                out.append(f"{prefix}ROBOT ID IN USE TWICE: {conflict.get('error')} "
                           f"({'; '.join(conflict.get('other_daemons') or [])}); fix: {conflict.get('fix')}")
        return out


def _subscribe(posed, robot: str, robots: Robots) -> list:
    """The Summaries fed by the client (:mod:`client`), one per robot: poses, status and fall events decoded;
    robots coming and going printed as they happen."""
    return [posed.on_pose(robot, lambda r, fit: robots.summary(r).on_pose(_Decoded(fit.to_json()))),
            posed.on_status(robot, lambda r, status: robots.summary(r).on_status(_Decoded(status.raw))),
            posed.on_event(robot, lambda r, event: robots.summary(r).on_event(_Decoded(event.to_json()))),
            posed.on_alive(lambda a: print(f"posed watch: robot {a.robot} {'up' if a.alive else 'gone'}",
                                           flush=True), robot)]


def _watch(args: argparse.Namespace) -> int:
    from posed.client import PosedClient
    from posed.commands._bus import open_client
    from posed.commands._viewer import Summary
    from posed.daemon.bus.session import daemon_endpoints

    cfg = config_from_args(args)
    endpoints = (args.connect,) if args.connect else daemon_endpoints(cfg.zenoh)
    args.connect = ", ".join(endpoints)
    session = open_client(cfg, endpoints, args.wait, "posed watch")
    if session is None:
        return 1
    t0 = time.monotonic()
    with session:
        if args.json:
            return _print_json(session, args, t0)
        robots = Robots(args.robot, _with_pause(Summary))
        keep = _subscribe(PosedClient(session), args.robot, robots)
        print(f"posed watch: {args.connect}, robot {args.robot} (Ctrl-C to stop)", flush=True)
        next_line = t0 + 1.0
        try:
            while not args.seconds or time.monotonic() - t0 < args.seconds:
                time.sleep(max(0.0, next_line - time.monotonic()))
                for line in robots.lines(next_line - t0):
                    print(line, flush=True)
                next_line += 1.0
        except KeyboardInterrupt:
            pass
        del keep
    return 0


def _print_json(session, args: argparse.Namespace, t0: float) -> int:
    """Every message as one JSON line, printed from the main thread (a closed pipe ends quietly)."""
    import queue

    lines: queue.Queue = queue.Queue(maxsize=10000)

    def on_sample(sample):
        try:
            value = json.loads(sample.payload.to_string())
        except ValueError:
            value = sample.payload.to_string()
        try:
            lines.put_nowait(json.dumps({"key": str(sample.key_expr), "value": value}))
        except queue.Full:
            pass

    keep = [session.declare_subscriber(f"posed/{args.robot}/**", on_sample)]
    try:
        while not args.seconds or time.monotonic() - t0 < args.seconds:
            try:
                print(lines.get(timeout=0.1), flush=True)
            except queue.Empty:
                continue
    except (KeyboardInterrupt, BrokenPipeError):
        sys.stderr.close()            # nothing more to say on a closed pipe
    del keep
    return 0
