"""Several people: the landmarker on two-person scenes composited from real footage (bench/people.py):
identity switches, each person found, the woman's landmark error with a second person in view against alone
(target at most 1.2x), speed. Run: ``posed bench people [--json] [--scenario NAME]``."""

from __future__ import annotations

import argparse
import json
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="", choices=("", "apart", "cross_behind", "cross_front"),
                        help="one scenario only (default: all)")


def run(args: argparse.Namespace) -> int:
    from posed.bench.people import run_bench  # not at import: `posed bench` lists this module
    from posed.daemon.preflight import shared_data

    report = run_bench(shared_data(), only=args.scenario,
                       progress=lambda m: print(m, file=sys.stderr, flush=True))
    if args.json:
        print(json.dumps(report))
        return 0
    print(f"{'scenario':13} {'switches A/B':>12} {'found A/B with other':>21} {'A err alone':>11} {'with B':>7} "
          f"{'ratio':>6} {'B dev':>6} {'ms/frame 2p':>11} {'1p':>6} {'passes':>6}")
    for r in report["scenarios"]:
        e = r["a_error_px"]
        print(f"{r['scenario']:13} {r['identity_switches']['a']:>5} / {r['identity_switches']['b']:<4} "
              f"{r['found']['a_both']:>9.2f} / {r['found']['b_both']:<9.2f} {e['alone']:>11} {e['with_b']:>7} "
              f"{e['ratio']!s:>6} {r['b_deviation_from_alone_px']!s:>6} {r['ms_per_frame']['two_people']:>11} "
              f"{r['ms_per_frame']['a_alone']:>6} {r['landmark_passes_per_frame']:>6}")
    return 0
