"""Fall detection: simulated falls and daily activities, the real fit, the detector (recall, false alarms, latency)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from daemon.commands import add_config_args, config_from_args

TARGETS = {"recall": 0.95, "false_alarms": 0, "median_latency_s": 1.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_args(parser, source=False)
    parser.add_argument("--split", choices=("tune", "heldout", "cmu", "all"), default="all",
                        help="which scenarios (tune: used to choose thresholds; heldout: never used to tune)")
    parser.add_argument("--only", default="", metavar="TEXT", help="only scenarios whose name contains TEXT")
    parser.add_argument("--truth", action="store_true",
                        help="skip the fit: feed the simulation's ground-truth joints (checks the detector alone)")
    parser.add_argument("--no-intrinsics", action="store_true",
                        help="do not give the fit the camera intrinsics (scaled orthographic fit, as a webcam "
                             "without calibration)")
    parser.add_argument("--markdown", metavar="FILE", help="also write the per-scenario table as Markdown")


def run(args: argparse.Namespace) -> int:
    from bench.falls import run_bench  # not at import: `posed` imports every bench module to list it
    from daemon.preflight import shared_data

    cfg = config_from_args(args)
    splits = ("tune", "heldout", "cmu") if args.split == "all" else (args.split,)
    shared = shared_data()

    def progress(o):
        if not args.json:
            lat = "" if o.latency_s is None else f" latency {o.latency_s:+.2f} s"
            mark = "ok " if o.detected == (o.kind == "fall") else "MISS" if o.kind == "fall" else "FALSE"
            print(f"{mark:5} {o.name:52} {','.join(o.states) or '-':28}{lat}", file=sys.stderr, flush=True)

    report = run_bench(splits, "truth" if args.truth else "real", cfg.falls, args.only, shared, progress,
                       fit_config=cfg.fitting, with_intrinsics=not args.no_intrinsics)
    if args.markdown:
        Path(args.markdown).write_text(markdown(report))
    if args.json:
        print(json.dumps(report))
    else:
        for split, s in report["splits"].items():
            print(f"{split:8} falls {s['falls']:3}  recall {_pct(s['recall'])}  ADL {s['adl']:3}  false alarms "
                  f"{s['false_alarms']}  median latency {s['median_latency_s']} s (max {s['max_latency_s']})")
        print(f"all      recall {_pct(report['recall'])}  false alarms {report['false_alarms']}  median latency "
              f"{report['median_latency_s']} s  ({report['seconds']} s, fit: {report['fit']})")
    ok = (report["recall"] is None or report["recall"] >= TARGETS["recall"]) and report["false_alarms"] == 0 and \
        (report["median_latency_s"] is None or report["median_latency_s"] <= TARGETS["median_latency_s"])
    return 0 if ok else 1


def _pct(v):
    return "  n/a" if v is None else f"{100 * v:5.1f}%"


def markdown(report: dict) -> str:
    lines = ["| scenario | kind | detected | latency (s) | messages | lowest pelvis (rel) | lowest pelvis lying (rel) |",
             "|---|---|---|---|---|---|---|"]
    for s in report["scenarios"]:
        lat = "" if s["latency_s"] is None else f"{s['latency_s']:.2f}"
        wrong = s["detected"] != (s["kind"] == "fall")
        det = ("**yes**" if wrong else "yes") if s["detected"] else ("**no**" if wrong else "no")
        low = "" if s["min_pelvis_rel"] is None else f"{s['min_pelvis_rel']:.2f}"
        lying = "" if s["min_pelvis_rel_lying"] is None else f"{s['min_pelvis_rel_lying']:.2f}"
        lines.append(f"| {s['name']} | {s['kind']} | {det} | {lat} | {', '.join(s['states'])} | {low} | {lying} |")
    return "\n".join(lines) + "\n"
