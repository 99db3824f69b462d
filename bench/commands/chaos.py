"""Chaos campaign against a real daemon on real inputs; fall events lost must be 0 (bench/chaos.py).

Kill -9 and SIGSTOP of stages, corrupt frames, an ack flood, a hanging and a chatty hook, a subscriber that comes
and goes; the report counts fall events produced, journaled, published, acknowledged and lost."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=60.0, help="chaos per input, seconds (default 60)")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    parser.add_argument("--input", choices=("both", "squat", "falls"), default="both",
                        help="the real squat video, a recording of real falls, or both (default)")
    parser.add_argument("--corrupt-every", type=int, default=25, metavar="N",
                        help="one frame in N is corrupt (0: none; default 25)")
    parser.add_argument("--ack-flood", type=int, default=20000, metavar="N",
                        help="hostile payloads put on events/ack once (default 20000)")
    parser.add_argument("--hook-megabytes", type=int, default=50, metavar="MB",
                        help="what the chatty hook prints per event (default 50)")
    parser.add_argument("--settle", type=float, default=45.0, metavar="S",
                        help="after the chaos, wait at most this long for every event to arrive (default 45)")
    parser.add_argument("--events-before-chaos", type=int, default=0, metavar="N",
                        help="start the chaos only once N fall-event messages arrived (default 0)")
    parser.add_argument("--no-stage-faults", action="store_true",
                        help="no kill -9 or SIGSTOP of stages (a control run for the other faults)")
    parser.add_argument("--web-idle", type=int, default=1000, metavar="N",
                        help="idle TCP connections held to the daemon's web stage while the page is probed "
                             "(0: web stage off; default 1000)")
    parser.add_argument("--no-storage-faults", action="store_true",
                        help="keep the state directory writable (default: a tmpfs of its own that goes read-only, "
                             "then full; needs root, reported as not run otherwise)")
    parser.add_argument("--no-crafted-images", action="store_true",
                        help="no crafted oversized JPEG headers among the squat frames")
    parser.add_argument("--no-clock-jumps", action="store_true",
                        help="no clock leaps, stalls and steps back in the falls recording")
    parser.add_argument("--work", metavar="DIR", help="keep the inputs, state and logs here (default: a "
                        "temporary folder, removed)")


def run(args: argparse.Namespace) -> int:
    from posed.bench.chaos import ChaosPlan, run_campaign  # not at import: `posed bench` lists this module
    from posed.daemon.preflight import shared_data

    if args.seconds <= 0 or min(args.corrupt_every, args.ack_flood, args.hook_megabytes, args.web_idle) < 0:
        print("posed bench chaos: --seconds must be > 0; --corrupt-every, --ack-flood, --hook-megabytes, "
              "--web-idle >= 0",
              file=sys.stderr)
        return 2
    inputs = ("squat", "falls") if args.input == "both" else (args.input,)
    plan = ChaosPlan(seconds=args.seconds, seed=args.seed, inputs=inputs, corrupt_every=args.corrupt_every,
                     ack_flood=args.ack_flood, hook_megabytes=args.hook_megabytes, settle_s=args.settle,
                     events_before_chaos=args.events_before_chaos, stage_faults=not args.no_stage_faults,
                     web_idle=args.web_idle, storage_faults=not args.no_storage_faults,
                     crafted_images=not args.no_crafted_images, clock_jumps=not args.no_clock_jumps)
    if args.work:
        Path(args.work).mkdir(parents=True, exist_ok=True)

    def progress(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    report = run_campaign(plan, shared_data(), progress, Path(args.work) if args.work else None)
    if args.json:
        print(json.dumps(report))
    else:
        for r in report["runs"]:
            e, m0, m1 = r["events"], r["memory_before"], r["memory_after"]
            print(f"{r['input']:6} faults kill9 {r['faults']['kill9']} sigstop {r['faults']['sigstop']}  events "
                  f"produced {e['produced']} journaled {e['journaled']} published {e['published']} received "
                  f"{e['received']} acknowledged {e['acknowledged']} lost {e['lost']}  longest gap "
                  f"{r['longest_publishing_gap_s']} s  restarts {r['restarts']}  memory {m0.get('memory_mb')} -> "
                  f"{m1.get('memory_mb')} MB  exit {r['exit_status']}")
            if r.get("web"):
                w = r["web"]
                print(f"       web: {w['idle_connections']} idle connections (opened in {w['opened_s']} s, "
                      f"{w['refused']} refused), {w['answered']}/{w['probes']} probes "
                      f"answered ({w['ok_answers']} ok), slowest {w['slowest_answer_s']} s")
            if r.get("storage"):
                st = r["storage"]
                print(f"       state directory: {st['error'] or st['faults']}; status storage states seen "
                      f"{st['status_states']}")
        t = report["totals"]
        print(f"total  produced {t['produced']} journaled {t['journaled']} published {t['published']} acknowledged "
              f"{t['acknowledged']} lost {t['lost']}  alarm violations {t['alarm_violations']} "
              f"(kills mid-fall {t['kills_mid_fall']})  ({report['seconds']} s)")
    ok = report["totals"]["lost"] == 0 and report["totals"]["alarm_violations"] == 0 and all(
        r["exit_status"] == 0 and r["daemon_survived_chaos"] and r["hooks_left_running"] == 0
        and (not r.get("web") or 0 < r["web"]["probes"] == r["web"]["answered"])
        and (not (r.get("storage") or {}).get("faults") or r["storage"]["status_states"].get("degraded", 0) > 0)
        for r in report["runs"])
    return 0 if ok else 1
