"""The 3D fit on simulated people: accuracy (angles, 3D joints, 2D error) and speed per frame.

``posed bench fit [--json] [--quick]``: the paper's six-pose protocol (image mode), lying/sitting/fallen poses,
motion sequences in video mode and the paper's Table 3 sweep; see docs/bench/fit.md.
"""

from __future__ import annotations

import argparse
import json
import sys

from daemon.commands import config_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="a smaller protocol (about a minute)")
    parser.add_argument("--config", metavar="FILE", help="config file whose fitting section is the base setting")
    parser.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                        help="override one config key, e.g. --set fitting.pose_prior=0")


def run(args: argparse.Namespace) -> int:
    from bench import fit as bench

    base = config_from_args(args).fitting
    plan = bench.QUICK if args.quick else bench.FULL
    progress = None if args.json else (lambda s: print(f"  running {s}", file=sys.stderr, flush=True))
    report = bench.run(plan, base, progress)
    if args.json:
        print(json.dumps(report))
    else:
        print(markdown(report))
    return 0


def markdown(report: dict) -> str:
    """The report as Markdown tables (the shape of docs/bench/fit.md)."""
    m = report["machine"]
    lines = [f"machine: {m['cpu']}, {m['cores']} cores, load {m['load_avg_1m']} ({m['note']})", ""]
    head = ("| protocol | optimizer | (restarts, max row) | mode | noise px | angle err deg | p90 | null-free | "
            "3D mm | 2D err (px) | loss | evals | ms/frame (CPU) | uDEAS ms | wall ms | failed |")
    lines += [head, "|" + "---|" * 16]
    for r in report["results"]:
        if r["protocol"] == "table3":
            continue
        lines.append(
            f"| {r['protocol']} | {r['optimizer']} | ({r['restarts']}, {r['max_row']}) | {r['mode']} | "
            f"{r['noise_px']} | {r['angle_err_deg']} | {r['angle_err_p90_deg']} | "
            f"{r.get('angle_err_null_free_deg', '')} | {r['mpjpe3d_mm']} | {r['err2d_px']} | {r['loss']} | "
            f"{r['evals']} | {r['ms_per_frame']} | {r['udeas_ms_per_frame']} | {r['wall_ms_per_frame']} | "
            f"{r['failed']}/{r['frames']} |")
    t3 = [r for r in report["results"] if r["protocol"] == "table3"]
    if t3:
        lines += ["", "Table 3 (paper's uDEAS alone, Table 1 bounds, noise-free six poses):", "",
                  "| restarts | max row | loss (x1e-3) | angle err deg | uDEAS ms/frame (CPU) | ms/frame |",
                  "|---|---|---|---|---|---|"]
        for r in t3:
            lines.append(f"| {r['restarts']} | {r['max_row']} | {r['loss'] * 1e3:.2f} | {r['angle_err_deg']} | "
                         f"{r['udeas_ms_per_frame']} | {r['ms_per_frame']} |")
    pp = [r for r in report["results"] if r["protocol"] == "paper_poses" and r["optimizer"] == "udeas+lm"
          and (r["restarts"], r["max_row"]) == (6, 6)]
    if pp:
        lines += ["", "Table 2 shape (uDEAS (6,6) + LM, per pose, mean angle error in degrees):", "",
                  "| noise px | " + " | ".join(pp[0]["per_case_angle_err_deg"]) + " | avg |",
                  "|---|" + "---|" * (len(pp[0]["per_case_angle_err_deg"]) + 1)]
        for r in pp:
            vals = list(r["per_case_angle_err_deg"].values())
            lines.append(f"| {r['noise_px']} | " + " | ".join(f"{v:.2f}" for v in vals) + f" | {r['angle_err_deg']} |")
    return "\n".join(lines)
