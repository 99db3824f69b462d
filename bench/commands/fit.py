"""The 3D fit on simulated people: accuracy (angles, 3D joints, 2D error) and speed per frame.

``posed bench fit [--json] [--quick] [--protocol NAME ...]``: in-domain (the model renders itself): the paper's
six-pose protocol (image mode), lying/sitting/fallen poses, motion sequences in video mode and the paper's
Table 3 sweep; out-of-domain: CMU motion capture seen by pinhole cameras all around (``ood_mocap``); see
docs/bench/fit.md.
"""

from __future__ import annotations

import argparse
import json
import sys

from posed.commands import config_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="a smaller protocol (about a minute)")
    parser.add_argument("--config", metavar="FILE", help="config file whose fitting section is the base setting")
    parser.add_argument("--set", metavar="KEY.PATH=VALUE", action="append", default=[], dest="overrides",
                        help="override one config key, e.g. --set fitting.pose_prior=0")
    parser.add_argument("--protocol", action="append", default=[], dest="protocols", metavar="NAME",
                        choices=("paper_poses", "floor_poses", "motion", "table3", "ood_mocap", "squat_video",
                                 "balancing_video"),
                        help="run only this protocol (repeat for several; default: all): paper_poses, "
                             "floor_poses, motion, table3 (in-domain), ood_mocap (out-of-domain), "
                             "squat_video (real video: video mode against image mode), balancing_video (real "
                             "video from 4 calibrated cameras with 3D truth, beside BlazePose's world landmarks)")


def run(args: argparse.Namespace) -> int:
    from posed.bench import fit as bench

    base = config_from_args(args).fitting
    plan = bench.QUICK if args.quick else bench.FULL
    progress = None if args.json else (lambda s: print(f"  running {s}", file=sys.stderr, flush=True))
    report = bench.run(plan, base, progress, protocols=args.protocols or None)
    if args.json:
        print(json.dumps(report))
    else:
        print(markdown(report))
    return 0


def markdown(report: dict) -> str:
    """The report as Markdown tables (the shape of docs/bench/fit.md)."""
    m = report["machine"]
    ref = m.get("speed_ref_ms") or {}
    lines = [f"machine: {m['cpu']}, {m['cores']} cores, load {m['load_avg_1m']}, speed reference "
             f"{ref.get('before')} ms before / {ref.get('after')} ms after ({m['note']})", ""]
    ind = [r for r in report["results"] if r.get("domain", "in-domain") == "in-domain" and r["protocol"] != "table3"]
    if ind:
        lines += ["In-domain (simulated people rendered from the fitted humanoid itself):", ""]
        lines += _in_domain(ind)
    ood = [r for r in report["results"] if r.get("domain") == "out-of-domain"]
    if ood:
        lines += ["", "Out-of-domain (ood_mocap: CMU motion capture, its own skeleton, pinhole cameras all around; "
                      "mean over clips and azimuths):", ""]
        lines += _out_of_domain(ood)
        cams = report["protocol"].get("ood_mocap", {}).get("cameras", [])
        if cams:
            lines += ["", "cameras (clip: azimuth deg -> distance m): " + "; ".join(
                f"{c['clip']} {c['azimuth_deg']:g} -> {c['distance_m']:g}" for c in cams)]
    sq = [r for r in report["results"] if r["protocol"] == "squat_video"]
    if sq:
        lines += ["", "Real squat video (squat_video: video mode against image mode, BlazePose's own landmarks):", "",
                  "| fps | median 2D err px image / video | frames image fits better | max knee diff there | "
                  "frames > 8 deg there | standing knee min image / video | ms image / video | targets | "
                  "same body: frames image fits better, max knee diff there, frames > 8 deg there |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in sq:
            e, k, ms = r["median_err2d_px"], r["standing_knee_min_deg"], r["ms_per_frame_median"]
            met = "met" if all(r["targets_met"].values()) else "MISSED: " + ", ".join(
                n for n, ok in r["targets_met"].items() if not ok)
            lines.append(f"| {r['fps']:g} | {e['image']} / {e['video']} | {r['frames_image_better']} | "
                         f"{r['knee_diff_max_where_image_better_deg']} | "
                         f"{r['frames_over_8deg_where_image_better'] or '-'} | {k['image']} / {k['video']} | "
                         f"{ms['image']} / {ms['video']} | {met} | {_same_body(r.get('same_body'))} |")
    bal = [r for r in report["results"] if r["protocol"] == "balancing_video"]
    if bal:
        from posed.bench.balancing_video import markdown as balancing_markdown
        from posed.bench.balancing_video import per_angle_markdown

        lines += ["", "Real video with 3D truth (balancing_video: 4 calibrated views, posed's own landmarks, the "
                      "cameras' intrinsics; the fit and BlazePose's world landmarks on the same frames):", ""]
        lines += balancing_markdown(bal)
        lines += ["", "Each angle (negative signed: read less bent than it is):", ""] + per_angle_markdown(bal)
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


def _out_of_domain(rows: list[dict]) -> list[str]:
    def v(x):
        return "null" if x is None else x

    lines = ["| body | mode | fps | noise px | noise corr s | depth (used) | world | PA-MPJPE mm | MPJPE mm | "
             "depth flips | angle err deg | root_cam err m | 2D err px | ms/frame (CPU) | p90 ms | failed |",
             "|" + "---|" * 16]
    for r in rows:
        lines.append(f"| {r.get('body', 'height')} | {r['mode']} | {r['fps']} | {r['noise_px']} | "
                     f"{r.get('noise_corr_s', 0.0):g} | {'yes' if r['depth'] else 'no'}"
                     f"{' (' + ('yes' if r['depth_used'] else 'no') + ')' if r['depth'] else ''} | "
                     f"{'yes' if r.get('world') else 'no'} | "
                     f"{v(r['pa_mpjpe_mm'])} | {v(r['mpjpe_mm'])} | {v(r['depth_flip_rate'])} | "
                     f"{v(r['angle_err_deg'])} | {v(r['root_cam_err_m'])} | {v(r['err2d_px'])} | "
                     f"{r['ms_per_frame']} | {r['ms_per_frame_p90']} | {r['failed']}/{r['frames']} |")
    return lines


def _in_domain(rows: list[dict]) -> list[str]:
    lines = []
    head = ("| protocol | optimizer | (restarts, max row) | mode | noise px | angle err deg | p90 | null-free | "
            "3D mm | 2D err (px) | loss | evals | ms/frame (CPU) | uDEAS ms | wall ms | failed |")
    lines += [head, "|" + "---|" * 16]
    for r in rows:
        lines.append(
            f"| {r['protocol']} | {r['optimizer']} | ({r['restarts']}, {r['max_row']}) | {r['mode']} | "
            f"{r['noise_px']} | {r['angle_err_deg']} | {r['angle_err_p90_deg']} | "
            f"{r.get('angle_err_null_free_deg', '')} | {r['mpjpe3d_mm']} | {r['err2d_px']} | {r['loss']} | "
            f"{r['evals']} | {r['ms_per_frame']} | {r['udeas_ms_per_frame']} | {r['wall_ms_per_frame']} | "
            f"{r['failed']}/{r['frames']} |")
    return lines


def _same_body(sb: dict | None) -> str:
    """The squat row's same-body comparison (bench.squat_video): image mode with video mode's own lengths."""
    if not sb:
        return "-"
    return (f"{sb['frames_image_better']}, {sb['knee_diff_max_where_image_better_deg']}, "
            f"{sb['frames_over_8deg_where_image_better'] or '-'}")
