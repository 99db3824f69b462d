"""``posed events [list] [--since T] [--until T] [--limit N] [--unacked] [--tz ZONE | --utc] [--json]``: list
stored fall events, each at the time it was journalled in the robot's zone with its UTC offset (the zone
``posed report`` and ``posed plot history`` use; ``--utc``: UTC, the listing as earlier versions printed it);
``posed events ack ID [--state S] [--by NAME]``: acknowledge one (a Zenoh put on ``posed/ROBOT/events/ack``;
``by``, who acknowledged, defaults to USER@HOST).

Rows of the journal that are not fall-event messages (damaged) are skipped and named in one line on stderr
with the sqlite3 command that shows them (--json: ``unreadable_rows``, their rowids).

Listing exit status: 0 listed (or no journal yet), 1 the journal cannot be read, 2 a bad option (a time that
cannot be read, --since after --until, a --journal that is a folder), 74 writing the list failed (a full
disk)."""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from posed.commands import add_config_args, config_from_args, config_path, positive_int
from posed.commands._paths import Output, OutputError
from posed.daemon.config.paths import EVENTS_FILE, reading_state_dir

STATES = ("falling", "on_floor", "alarm", "recovered")  # falls.FALL_STATES (not imported: no numpy here)
MAX_BY_CHARS = 128                                      # daemon.bus.acks.MAX_BY_CHARS
SHOW_ROWIDS = 20                                        # unreadable journal rows named by rowid
CLOCK_NOTES = {"behind": "alarm raised at once: the clock was stepped back",
               "beyond_horizon": "alarm raised at once: the fall is more than a day old by this clock and nobody "
                                 "acknowledged it"}     # restored.clock (docs/falls.md, "The alarm across a restart")


def default_by() -> str:
    """Who acknowledges when ``--by`` is not given: USER@HOST (the login name, else $USER, else the uid)."""
    import getpass
    import socket

    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = os.environ.get("USER") or f"uid{os.getuid()}"
    return f"{user}@{socket.gethostname() or 'localhost'}"


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("events", help="list the fall events stored in the journal, or acknowledge one",
                            description="Without an action: list (as `posed events list`).")
    _list_options(parser)
    parser.set_defaults(func=run)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    listing = actions.add_parser("list", help="list the stored fall events (the default)")
    _list_options(listing)
    listing.set_defaults(func=run)
    ack = actions.add_parser(
        "ack", help="acknowledge a fall event: the daemon stops republishing it",
        description="Puts {\"id\": ID, \"state\": S, \"by\": NAME} on posed/ROBOT/events/ack of the running "
                    "daemon (its endpoint and robot id from the config). An id prefix, as `posed events` prints "
                    "it, is completed from the journal when the journal is readable.")
    add_config_args(ack, source=False, example="robot_id=kitchen")
    ack.add_argument("id", metavar="ID", help="the event id (or a unique prefix of it)")
    ack.add_argument("--state", choices=STATES,
                     help="acknowledge only this message of the event (default: every message so far)")
    ack.add_argument("--by", metavar="NAME", default=None,
                     help="who acknowledges, kept in the journal and shown by `posed events` (free text, at most "
                          f"{MAX_BY_CHARS} characters; default: your user name and this host, USER@HOST; "
                          "--by '' sends none)")
    ack.add_argument("--connect", metavar="ENDPOINT",
                     help="the daemon's Zenoh endpoint (default: from the config's zenoh.listen, e.g. "
                          "tcp/127.0.0.1:7447)")
    ack.add_argument("--robot", metavar="ROBOT", help="robot id (default: the config's robot_id)")
    ack.add_argument("--journal", metavar="FILE",
                     help="journal file to complete the id and confirm the ack (default: the state dir's)")
    ack.add_argument("--wait", type=float, default=5.0, metavar="S",
                     help="keep trying to connect, then to see the ack in the journal, this long (default 5 s)")
    ack.set_defaults(func=run_ack)


def _list_options(parser: argparse.ArgumentParser) -> None:
    from posed.commands.history import add_zone_args

    add_config_args(parser, source=False, example="pipeline.state_dir=/var/lib/posed")
    parser.add_argument("--since", metavar="TIME", help="from this time: 2h, 7d, today, 2024-05-01T14:00, ...")
    parser.add_argument("--until", metavar="TIME", help="up to this time (same forms as --since)")
    parser.add_argument("--limit", type=positive_int, default=None, metavar="N",
                        help="only the newest N messages (of those --unacked and the times select)")
    parser.add_argument("--unacked", action="store_true", help="only messages not yet acknowledged")
    parser.add_argument("--journal", metavar="FILE", help="journal file (default: events.sqlite3 in the state dir)")
    add_zone_args(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object (times as unix seconds and ISO "
                                                            "UTC, whatever the zone)")


def journal_path(args: argparse.Namespace, cfg=None) -> Path:
    """``--journal``, else events.sqlite3 in the state dir a reading command opens (daemon.config.paths)."""
    if args.journal:
        return Path(args.journal)
    cfg = cfg or config_from_args(args)
    return reading_state_dir(cfg.pipeline, config_path(args), EVENTS_FILE) / EVENTS_FILE


def run(args: argparse.Namespace) -> int:
    from posed.commands.history import display_zone, time_range
    from posed.daemon.outbox.journal import EventJournal, JournalError  # not at import: it pulls in structlog

    try:
        tz = display_zone(args)
        since, until = time_range(args, tz)
    except ValueError as exc:
        print(f"posed events: {exc}", file=sys.stderr)
        return 2
    path = journal_path(args)
    if path.is_dir():
        print(f"posed events: {path} is a folder, not an event journal: give the journal file, e.g. --journal "
              f"{path / EVENTS_FILE}", file=sys.stderr)
        return 2
    if path.parent.is_dir() and not os.access(path.parent, os.R_OK | os.X_OK):
        print(f"posed events: cannot read {path.parent} (permission denied){_permission_hint(path, PermissionError())}",
              file=sys.stderr)
        return 1
    if not path.is_file():
        return _print_listing(args, path, None)
    try:
        with EventJournal(path, readonly=True) as journal:
            stored = journal.query(since, until, args.limit, unacked=args.unacked)
            unreadable = sorted(journal.unreadable_rows)
    except FileNotFoundError:       # gone, or being created by the daemon this moment: no event yet
        return _print_listing(args, path, None)
    except (JournalError, PermissionError) as exc:
        print(f"posed events: {exc}{_permission_hint(path, exc)}", file=sys.stderr)
        return 1
    if unreadable:
        print(unreadable_line(path, unreadable), file=sys.stderr)
    return _print_listing(args, path, stored, hooks_kept=_keeps_hooks(path), unreadable=unreadable, tz=tz)


def unreadable_line(path: Path, rowids: list[int]) -> str:
    """One line naming the journal's rows that are not fall-event messages (damaged by hand, a disk, a bug; the
    journal skips them) and the sqlite3 command that shows them."""
    import shlex

    shown = ", ".join(str(r) for r in rowids[:SHOW_ROWIDS]) + (", ..." if len(rowids) > SHOW_ROWIDS else "")
    query = f"SELECT rowid, * FROM messages WHERE rowid IN ({', '.join(str(r) for r in rowids[:SHOW_ROWIDS])})"
    return (f"posed events: {len(rowids)} row(s) of the journal could not be read (not fall-event messages: "
            f"damaged) and are not listed (rowid {shown}); look at them: sqlite3 {shlex.quote(str(path))} "
            f"{shlex.quote(query)}")


def _keeps_hooks(path: Path) -> bool:
    """Whether the journal records when the hooks were done with each message (an older posed's journal, not
    yet opened by a newer daemon, does not: its messages' hooks are not known, never "pending")."""
    import sqlite3

    from posed.daemon.outbox.journal_rows import table_columns

    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            return "hooks_outcome" in table_columns(db, "messages")
        finally:
            db.close()
    except sqlite3.Error:
        return True


def notes(extra: dict) -> str:
    """What a reader must know beside the state: the fall was taken back after a restart (``restored``; its alarm
    raised at once for a stepped clock: ``restored.clock``), the alarm was raised with no camera frame
    (``without_frames_s``)."""
    out = []
    restored = extra.get("restored")
    if isinstance(restored, dict):
        out.append(f"taken back after a restart (was {restored.get('last_state') or '?'})")
        clock = restored.get("clock")
        if isinstance(clock, str) and clock:
            out.append(CLOCK_NOTES.get(clock, f"clock: {clock}"))
    blind = extra.get("without_frames_s")
    if isinstance(blind, (int, float)) and not isinstance(blind, bool):
        out.append(f"raised with no camera frame for {blind:.0f} s")
    return "; ".join(out)


def _print_listing(args: argparse.Namespace, path: Path, stored, hooks_kept: bool = True,
                   unreadable: list[int] = (), tz=None) -> int:
    """The list on standard output (``stored`` None: there is no journal yet); 74 when it cannot be written.
    ``unreadable``: the rowids of the journal's rows that could not be read (said on stderr; in --json);
    ``tz``: the zone of the times (``--utc``: the journal's own UTC text, as earlier versions printed it)."""
    from posed.daemon.timeparse import clock_text, future_note, zone_name

    out = Output("posed events", None)
    out.open()
    try:
        if args.json:
            events = [] if stored is None else [s.to_json() for s in stored]
            print(json.dumps({"journal": str(path), "events": events, "unreadable_rows": list(unreadable)}),
                  file=out)
        elif stored is None:
            print(f"no event journal at {path} yet (the daemon creates it with its first fall event)", file=out)
        elif not stored:
            print(f"no events in {path} for that time range", file=out)
        else:
            utc = tz is None or getattr(args, "utc", False)
            head = "wall time (UTC)" if utc else f"time ({zone_name(tz)})"
            width = 24 if utc else 26
            print(f"{head:<{width}} {'event':<12} {'state':<10} {'conf':>5} {'pub':>3} {'ack':>3} "
                  f"{'acked by':<16} {'hooks':<9}  features", file=out)
            now = time.time()
            for s in stored:
                e = s.event
                by = (s.acked_by or "-") if s.acked_at else ""
                when = e.wall_time[:23] if utc else clock_text(s.wall, tz)
                said = [n for n in (notes(e.extra), future_note(s.wall, now)) if n]
                print(f"{when:<{width}} {e.id[:12]:<12} {e.state:<10} {e.confidence:5.2f} "
                      f"{'yes' if s.published_at else 'no':>3} {'yes' if s.acked_at else 'no':>3} "
                      f"{_cut(by, 16):<16} {s.hooks_outcome or ('pending' if hooks_kept else 'not kept'):<9}  "
                      f"{','.join(e.features)}" + (f"  [{'; '.join(said)}]" if said else ""), file=out)
        out.close()
    except OutputError as exc:
        return out.failed(exc.exc)
    return 0


def _cut(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 1] + "…"


def _permission_hint(path: Path, exc: BaseException) -> str:
    if isinstance(exc, PermissionError) or "permission" in str(exc).lower():
        return (f"\n  {path.parent} belongs to the service: run as its user (sudo -u posed posed events) or "
                "with sudo")
    return ""


def _read_journal(path: Path):
    """Every stored message, or None when the journal is missing or unreadable (the ack is sent anyway)."""
    from posed.daemon.outbox.journal import EventJournal, JournalError

    if not path.is_file():
        return None
    try:
        with EventJournal(path, readonly=True) as journal:
            return journal.query()
    except (JournalError, OSError):
        return None


def _of_robot(stored, robot: str | None):
    """The stored messages of ``robot`` (None: all of them); None when there are none (as no journal)."""
    if stored is None or robot is None:
        return stored
    return [s for s in stored if s.event.robot == robot] or None


def run_ack(args: argparse.Namespace) -> int:
    from posed.commands._bus import open_client
    from posed.daemon.bus.session import daemon_endpoints

    cfg = config_from_args(args)
    event_id = args.id.strip()
    if not event_id:
        print("posed events ack: the event id is empty; `posed events` lists them", file=sys.stderr)
        return 2
    by = default_by() if args.by is None else args.by.strip()
    if len(by) > MAX_BY_CHARS or not by.isprintable():
        print(f"posed events ack: --by must be at most {MAX_BY_CHARS} printable characters", file=sys.stderr)
        return 2
    robot = args.robot or cfg.robot_id
    path = journal_path(args, cfg)
    # the local journal is the config's robot's: another robot's ack (--robot B on robot A's machine) completes
    # and confirms only from that robot's rows there, else through that robot's history over Zenoh
    other_robot = not args.journal and robot != cfg.robot_id
    stored = _of_robot(_read_journal(path), robot if other_robot else None)
    if stored is not None:
        ids = sorted({s.event.id for s in stored if s.event.id.startswith(event_id)})
        if event_id not in ids and len(ids) == 1:
            event_id = ids[0]
        elif len(ids) > 1 and event_id not in ids:
            print(f"posed events ack: {args.id!r} is the start of {len(ids)} event ids ({', '.join(ids[:5])}); "
                  "give more of it", file=sys.stderr)
            return 2
        elif not ids:
            print(f"posed events ack: {event_id!r} is not in {path}; sending it anyway", file=sys.stderr)
        states = [s.event.state for s in stored if s.event.id == event_id]
        if states and args.state and args.state not in states:
            print(f"posed events ack: event {event_id} has no {args.state!r} message (its messages so far: "
                  f"{', '.join(dict.fromkeys(states))}); acknowledge one of those with --state, or the whole "
                  "event without --state", file=sys.stderr)
            return 2
    endpoints = (args.connect,) if args.connect else daemon_endpoints(cfg.zenoh)
    session = open_client(cfg, endpoints, args.wait, "posed events ack")
    if session is None:
        return 1
    key = f"posed/{robot}/events/ack"
    with session:
        from posed.client import PosedClient

        # the client puts the ack (posed.ack JSON) and, reading the robot's event history over Zenoh, puts it
        # again until the daemon shows it acknowledged (a put racing the route to the daemon can be lost)
        confirmed = PosedClient(session).ack(robot, event_id, args.state, by=by or None, confirm_s=args.wait)
        what = f"event {event_id}" + (f" ({args.state})" if args.state else "")
        print(f"posed events ack: sent {what}" + (f" by {by!r}" if by else "") +
              f" to {key} via {', '.join(endpoints)}", flush=True)
        if stored is None:
            if confirmed:
                print(f"posed events ack: robot {robot} acknowledged {what} (its event history says so)")
                return 0
            print(f"posed events ack: robot {robot}'s event history does not show {what} acknowledged after "
                  f"{args.wait:g} s (is its daemon running, is the id right" + (
                      f", and has the event a {args.state!r} message yet" if args.state else "") + "?)",
                  file=sys.stderr)
            return 1
        # confirm from the journal the daemon writes (readable when it is ours or we may read the service's)
        deadline = time.monotonic() + args.wait
        while time.monotonic() < deadline:
            mine = [s for s in (_of_robot(_read_journal(path), robot if other_robot else None) or [])
                    if s.event.id == event_id and (args.state is None or s.event.state == args.state)]
            if mine and all(s.acked_at for s in mine):
                kept = ", ".join(dict.fromkeys(s.acked_by or "(not said)" for s in mine))
                print(f"posed events ack: the daemon acknowledged {what} in {path} (acknowledged by: {kept})")
                return 0
            time.sleep(0.2)
    print(f"posed events ack: {path} does not show {what} acknowledged after {args.wait:g} s (is the daemon "
          f"for robot {robot} running and using that journal?)", file=sys.stderr)
    return 1
