"""Fall detection: simulated falls and daily activities (in-domain: the simulation's own body), and labelled
real recordings (``--recordings DIR``), through the real fit and the detector (recall, false alarms, latency)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from posed.commands import add_config_args, config_from_args

TARGETS = {"recall": 0.95, "false_alarms": 0, "median_latency_s": 1.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_args(parser, source=False)
    parser.add_argument("--split", choices=("tune", "heldout", "cmu", "all", "none"), default="all",
                        help="which simulated scenarios (tune: used to choose thresholds; heldout: never used to "
                             "tune; none: only --recordings)")
    parser.add_argument("--recordings", metavar="DIR",
                        help="also score a folder of labelled real recordings (*.landmarks.jsonl + labels.json, "
                             "as shared/data/falls/urfd_dev)")
    parser.add_argument("--geometry", choices=("labels", "config"), default="labels",
                        help="recordings: camera tilt/roll/height from labels.json (default) or from the config "
                             "(e.g. --set falls.camera_tilt_auto=true)")
    parser.add_argument("--synthetic-geometry", choices=("given", "unknown", "auto", "imu", "default"),
                        default="given",
                        help="simulated scenarios: the camera's true tilt, roll and height in the config (given), "
                             "tilt and roll 0 and nothing learned (unknown), 0 and learned from the person (auto), "
                             "0 with an accelerometer's gravity on every frame (imu), or the config as it is "
                             "(default: tilt 0, height 1 m, a daemon told nothing about the camera)")
    parser.add_argument("--mount", choices=("robot", "wall", "corner"), default="robot",
                        help="simulated scenarios and CMU clips: the robot's camera (0.9-1.3 m, 8-22 deg down, "
                             "640x480, intrinsics given), a wall camera (2 m, 35 deg down, 320x240, 62 deg, no "
                             "intrinsics given to the fit or the detector: both assume falls.camera_hfov_deg's "
                             "lens, as the daemon does) or a second one in a room's corner, never used while "
                             "building the detector (2.4 m, 25 deg down, 320x240, 74 deg, no intrinsics)")
    parser.add_argument("--world", action="store_true",
                        help="simulated scenarios and CMU clips: give the fit BlazePose world landmarks with every "
                             "frame, as the daemon's landmark stage does (simulated from the true joints with the "
                             "error measured on real video: bench/falls_world.py); without it the fit has the 2D "
                             "landmarks only")
    parser.add_argument("--extractor", choices=("blazepose", "holistic"), default="blazepose",
                        help="simulated scenarios and CMU clips: the 2D landmarks as this extractor gives them: "
                             "blazepose (all 33, posed's landmark stage) or holistic (MediaPipe Holistic as on the "
                             "real urfd_dev recordings: no elbows, a wrist on 9 %% of frames, 3 of 8 falls losing "
                             "the person after the impact: bench/falls_extractor.py)")
    parser.add_argument("--no-cache", action="store_true",
                        help="fit again, do not use the cached fits (~/.cache/posed/falls-fits)")
    parser.add_argument("--only", default="", metavar="TEXT", help="only scenarios whose name contains TEXT")
    parser.add_argument("--truth", action="store_true",
                        help="skip the fit: feed the simulation's ground-truth joints (checks the detector alone)")
    parser.add_argument("--no-intrinsics", action="store_true",
                        help="do not give the fit the camera intrinsics: it gets the assumed lens of "
                             "falls.camera_hfov_deg, as the daemon fits a webcam without calibration (--set "
                             "fitting.projection=orthographic: the scaled orthographic fit)")
    parser.add_argument("--markdown", metavar="FILE", help="also write the per-scenario table as Markdown")
    parser.add_argument("--assume-fov", action="store_true",
                        help="no effect: a fit without intrinsics (--mount wall, --no-intrinsics) now always "
                             "projects through the assumed lens of falls.camera_hfov_deg, as the daemon's; kept "
                             "so the earlier commands in docs/benchmarks.md still run")
    parser.add_argument("--cross-source", action="store_true",
                        help="the cross-source check: the same detector on every source (synthetic robot, wall and "
                             "corner cameras, with and without world landmarks and with Holistic's landmarks, CMU, "
                             "--recordings or shared urfd_dev, real videos through posed landmarks), "
                             "each row saying whether values were chosen on it, with the gap to that source")
    parser.add_argument("--camera", metavar="MOTION[,MOTION]",
                        help="the moving-camera protocol instead: the simulated scenarios and CMU clips (--split, "
                             "--only, --truth) seen by a robot head that stays still (static), tilts to follow the "
                             "person's pelvis (follow: 0.15 s delay, 0.15 s servo, at most 60 deg/s) or scans the "
                             "room (nod: +-12 deg every 6 s), pans and tilts to follow it (follow_pan: the same, at "
                             "most 80 deg/s in pan) or rides a base that drives to keep 2 m from the person, facing "
                             "them (drive: at most 0.5 m/s, 0.5 / 0.6 m/s^2, the head as follow_pan; the IMU feels "
                             "the base's acceleration); comma-separated, or all. Each is scored with the "
                             "default config, the home mount configured as measured, and the true mount of every "
                             "frame given through FallDetector.set_camera_mount, with and without its height, "
                             "and the head's accelerometer as hal.imu filters it, alone (imu) and with the camera's gyro "
                             "(imu_gyro: BMI055-like noise and bias) (bench/falls_moving.py); "
                             "--synthetic-geometry does not apply")


CAMERA_MOTIONS = ("static", "follow", "nod", "follow_pan", "drive")


def _camera_motions(value: str) -> list[str] | str:
    """The motions of ``--camera`` (a list), or what is wrong with it (a string)."""
    names = [m.strip() for m in value.split(",") if m.strip()]
    if names == ["all"]:
        return list(CAMERA_MOTIONS)
    bad = [m for m in names if m not in CAMERA_MOTIONS]
    if bad or not names:
        return f"--camera takes {', '.join(CAMERA_MOTIONS)} or all (comma-separated), not {value!r}"
    return [m for m in CAMERA_MOTIONS if m in names]   # static first: the others are compared with it


def _camera(args, cfg, splits, shared) -> int:
    from posed.bench.falls_moving import print_report, run_protocol
    from posed.daemon.preflight import cache_dir

    motions = _camera_motions(args.camera)
    clash = [flag for flag, on in (("--mount " + args.mount, args.mount != "robot"), ("--world", args.world),
                                   ("--extractor " + args.extractor, args.extractor != "blazepose"),
                                   ("--recordings", bool(args.recordings)), ("--cross-source", args.cross_source),
                                   ("--no-intrinsics", args.no_intrinsics), ("--markdown", bool(args.markdown)))
             if on]
    if isinstance(motions, str) or clash or not splits:
        why = motions if isinstance(motions, str) else (
            f"--camera runs the robot camera's scenarios only: drop {', '.join(clash)}" if clash
            else "--camera needs simulated scenarios: --split tune, heldout, cmu or all")
        print(f"posed bench falls: {why}", file=sys.stderr)
        return 2

    def progress(motion, arm, o):
        if not args.json:
            oc = o.outcome
            lat = "" if oc.latency_s is None else f" latency {oc.latency_s:+.2f} s"
            mark = "ok " if oc.detected == (oc.kind == "fall") else "MISS" if oc.kind == "fall" else "FALSE"
            print(f"{mark:5} {arm:10} {oc.name:60} {','.join(oc.states) or '-':28}{lat}", file=sys.stderr,
                  flush=True)

    report = run_protocol(motions, splits, "truth" if args.truth else "real", cfg.falls, args.only, shared,
                          fit_config=cfg.fitting, cache=None if args.no_cache else cache_dir() / "falls-fits",
                          progress=progress)
    if args.json:
        print(json.dumps(report))
    else:
        print_report(report)
    return 0


def run(args: argparse.Namespace) -> int:
    from posed.bench.falls import run_bench  # not at import: `posed` imports every bench module to list it
    from posed.daemon.preflight import shared_data

    if args.camera is not None:
        cfg = config_from_args(args)
        splits = {"all": ("tune", "heldout", "cmu"), "none": ()}.get(args.split, (args.split,))
        return _camera(args, cfg, splits, shared_data())
    if args.world and args.extractor != "blazepose":
        print(f"posed bench falls: --world gives the fit BlazePose's world landmarks, which --extractor "
              f"{args.extractor} does not have: drop one of the two", file=sys.stderr)
        return 2
    cfg = config_from_args(args)
    splits = {"all": ("tune", "heldout", "cmu"), "none": ()}.get(args.split, (args.split,))
    shared = shared_data()
    if args.cross_source:
        return _cross(args, cfg, shared)
    real = _recordings(args, cfg) if args.recordings else None
    if not splits:
        if args.json:
            print(json.dumps({"recordings": real}))
        elif real is not None:
            _print_recordings(real)
        return 0 if real is None or _recordings_ok(real) else 1

    def progress(o):
        if not args.json:
            lat = "" if o.latency_s is None else f" latency {o.latency_s:+.2f} s"
            mark = "ok " if o.detected == (o.kind == "fall") else "MISS" if o.kind == "fall" else "FALSE"
            print(f"{mark:5} {o.name:52} {','.join(o.states) or '-':28}{lat}", file=sys.stderr, flush=True)

    from posed.daemon.preflight import cache_dir

    report = run_bench(splits, "truth" if args.truth else "real", cfg.falls, args.only, shared, progress,
                       fit_config=cfg.fitting, with_intrinsics=not args.no_intrinsics,
                       cache=None if args.no_cache else cache_dir() / "falls-fits",
                       geometry=args.synthetic_geometry, mount=args.mount, world=args.world,
                       extractor=args.extractor)
    if args.markdown:
        Path(args.markdown).write_text(markdown(report))
    if real is not None:
        report["recordings"] = real
    if args.json:
        print(json.dumps(report))
    else:
        print("synthetic protocol (in-domain: scenarios rendered from posed's own stick body):")
        for split, s in report["splits"].items():
            print(f"{split:8} falls {s['falls']:3}  recall {_pct(s['recall'])}  ADL {s['adl']:3}  false alarms "
                  f"{s['false_alarms']}  median latency {s['median_latency_s']} s (max {s['max_latency_s']})")
        print(f"all      recall {_pct(report['recall'])}  false alarms {report['false_alarms']}  median latency "
              f"{report['median_latency_s']} s  ({report['seconds']} s, fit: {report['fit']}"
              f"{', with world landmarks' if report['world'] else ''}"
              f"{'' if args.extractor == 'blazepose' else f'; landmarks as {args.extractor} gives them'}; camera geometry: {report['geometry']['mode']})")
    if real is not None and not args.json:
        _print_recordings(real)
    ok = (real is None or _recordings_ok(real)) and (report["recall"] is None or report["recall"] >= TARGETS["recall"]) and report["false_alarms"] == 0 and \
        (report["median_latency_s"] is None or report["median_latency_s"] <= TARGETS["median_latency_s"])
    return 0 if ok else 1


def _cross(args, cfg, shared) -> int:
    from posed.bench.falls_cross import run_cross, table
    from posed.daemon.preflight import cache_dir

    recordings = Path(args.recordings) if args.recordings else shared / "falls" / "urfd_dev"
    cache = None if args.no_cache else cache_dir() / "falls-fits"
    report = run_cross(shared, cfg, recordings, cache, cache_dir() / "falls-videos",
                       log=(lambda s: None) if args.json else (lambda s: print(s, file=sys.stderr, flush=True)))
    if args.markdown:
        Path(args.markdown).write_text(table(report))
    if args.json:
        print(json.dumps(report))
    else:
        print(f"cross-source check (gaps against {report['reference']}):")
        print(table(report), end="")
        for v in report["videos"]:
            print(f"  {v['video']}: {v['what']}: {', '.join(v['states']) or 'nothing'}")
    return 0


RECORDING_TARGETS = {"recall": 7 / 8, "false_alarm_rate": 1 / 19, "median_latency_s": 1.0}


def _recordings(args, cfg) -> dict:
    from posed.bench.falls_recordings import run_recordings
    from posed.daemon.preflight import cache_dir

    def progress(o):
        if not args.json:
            lat = "" if o.latency_s is None else f" latency {o.latency_s:+.2f} s"
            mark = "ok " if o.detected == (o.kind == "fall") else "MISS" if o.kind == "fall" else "FALSE"
            conf = "" if o.confidence is None else f" conf {o.confidence:.2f}"
            print(f"{mark:5} {o.name:24} {','.join(o.states) or '-':28}{lat}{conf} {','.join(o.features)}",
                  file=sys.stderr, flush=True)

    cache = None if args.no_cache else cache_dir() / "falls-fits"
    return run_recordings(Path(args.recordings), cfg, args.geometry, cache, args.only, progress)


def _recordings_ok(r: dict) -> bool:
    return ((r["recall"] is None or r["recall"] >= RECORDING_TARGETS["recall"] - 1e-9)
            and r["false_alarms"] <= RECORDING_TARGETS["false_alarm_rate"] * max(r["adl"], 1) + 1e-9
            and (r["median_latency_s"] is None or r["median_latency_s"] <= RECORDING_TARGETS["median_latency_s"]))


def _print_recordings(r: dict) -> None:
    print(f"recordings {r['folder']} (real, out of domain; geometry: {r['geometry']}):")
    print(f"         falls {r['falls']:3}  recall {_pct(r['recall'])} ({r['detected']}/{r['falls']})  ADL {r['adl']:3}  "
          f"false alarms {r['false_alarms']}  median latency {r['median_latency_s']} s (max {r['max_latency_s']})")


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
