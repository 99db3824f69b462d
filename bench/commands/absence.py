"""The "not seen for longer than usual" notice on SIMULATED households: false notices a month and how long after a
fall out of view the notice comes (a model of routines, not a measurement; docs/bench/absence.md).

Simulated households (bench/absence.py: wake and bed times, passes through the camera's room, meals, television,
outings) write the per-minute table posed's history keeps; each absence is judged with the real
``falls.absence.usual_absence`` as the daemon judges it, for the rule's window of 1.5 h (the default), with the
window off and with 2 h. The window and the 1 h margin were set from studies before this benchmark: it shows them in
context, it is not for tuning them.

Run: ``posed bench absence [--json] [--households N] [--days D] [--seed S]``.
"""

from __future__ import annotations

import argparse
import json
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--households", type=int, default=200, metavar="N", help="simulated households (default 200)")
    parser.add_argument("--days", type=int, default=60, metavar="D",
                        help="days per household (default 60; the first 14 only teach the routine)")
    parser.add_argument("--seed", type=int, default=None, help="the simulation's seed (default 0)")


def run(args: argparse.Namespace) -> int:
    from posed.bench import absence  # not at import: `posed bench` lists this module

    if args.households < 1 or args.days < 1:
        print("posed bench absence: --households and --days must be at least 1", file=sys.stderr)
        return 2
    plan = absence.Plan(households=args.households, days=args.days,
                        seed=absence.SEED if args.seed is None else args.seed)
    report = absence.run_bench(plan, progress=lambda m: print(m, file=sys.stderr, flush=True))
    if args.json:
        print(json.dumps(report))
    else:
        print("\n".join(absence.table(report)))
    return 0
