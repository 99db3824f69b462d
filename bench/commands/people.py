"""Several people (bench/people.py, bench/people_falls.py, bench/people_recordings.py). Parts:

* ``scenes``: the landmarker on two-person scenes composited from real footage: identity switches, each person
  found, the woman's landmark error with a second person in view against alone (target at most 1.2x), speed;
* ``falls``: the synthetic fall scenarios (``--split``, default heldout) with a bystander standing, walking or
  kneeling beside the person who fell, the real fit per person: recall, false alarms, bystander events, second
  events, events ended, identity switches, against the same scenarios alone, and the faller's 3D error (PA-MPJPE
  of the 12 body joints) on the frames both runs fitted, where the bystander covers them and where not;
  ``--occlusion``: the landmarks
  one person's body covers of the other's as the landmark stage gives them; ``--kneel-at camera``: the kneeling
  bystander between the camera and the person who fell;
* ``recordings``: the real fall recordings of shared/data/falls/urfd_dev each with a real bystander (another
  clip's person beside the camera's axis), through what ``posed falls`` runs, against alone;
* ``stature``: who is who: a man's shoulder height measured from one real image by each of four calibrated
  cameras (what the household recognition measures), against his triangulated joints.

Run: ``posed bench people [--json] [--part scenes|falls|recordings|stature] [--scenario NAME]
[--b-camera CAM] [--crossings N [--seed S]] [--split S] [--occlusion] [--kneel-at side|camera]``."""

from __future__ import annotations

import argparse
import json
import sys

PARTS = ("scenes", "falls", "recordings", "stature")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--part", action="append", choices=PARTS,
                        help="run only this part (repeatable; default: all)")
    parser.add_argument("--scenario", default="", choices=("", "apart", "cross_behind", "cross_front",
                                                             "cross_behind_ltr", "cross_front_ltr"),
                        help="scenes: one scenario only (default: all)")
    parser.add_argument("--b-camera", default="cam03", choices=("cam01", "cam02", "cam03", "cam04"),
                        help="scenes: the pose2sim view B is cut from (default cam03, the reported one; cam01, "
                             "cam02 and cam04 are development views)")
    parser.add_argument("--crossings", type=int, default=0, metavar="N",
                        help="scenes: N crossings drawn at random (B in front and behind, either way, at "
                             "random scales and paths) instead of the five fixed scenarios, with a summary")
    parser.add_argument("--seed", type=int, default=0, help="scenes: the seed of --crossings (default 0)")
    parser.add_argument("--occlusion", action="store_true",
                        help="falls: each person's landmarks that the other's body covers are moved as posed's "
                             "landmark stage was measured to move them, and a person 40 %% covered or more is "
                             "not found (bench/people_occlusion.py)")
    parser.add_argument("--kneel-at", default="side", choices=("side", "camera"),
                        help="falls: the kneeling bystander kneels at the faller's side (default) or between "
                             "the camera and the faller")
    parser.add_argument("--split", default="heldout", choices=("tune", "heldout"),
                        help="falls: the scenario split (default: heldout, never used to tune)")


def run(args: argparse.Namespace) -> int:
    from posed.daemon.preflight import shared_data

    parts = args.part or list(PARTS)
    progress = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    report: dict = {"benchmark": "people"}
    if "scenes" in parts:
        from posed.bench.people import run_bench  # not at import: `posed bench` lists this module

        report["scenes"] = run_bench(shared_data(), only=args.scenario, progress=progress,
                                     b_camera=args.b_camera, crossings=args.crossings, seed=args.seed)
    if "falls" in parts:
        from posed.bench.people_falls import run_bench as run_falls

        report["falls"] = run_falls(args.split, progress=progress, occlude=args.occlusion, kneel_at=args.kneel_at)
    if "recordings" in parts:
        from posed.bench.people_recordings import run as run_recordings

        folder = shared_data() / "falls" / "urfd_dev"
        report["recordings"] = {g: run_recordings(folder, geometry=g, progress=progress)
                                for g in ("config", "labels")}
    if "stature" in parts:
        from posed.bench.people_stature import run as run_stature

        report["stature"] = run_stature(shared_data())
    if args.json:
        print(json.dumps(report))
        return 0
    if "scenes" in report:
        _print_scenes(report["scenes"])
    if "falls" in report:
        _print_falls(report["falls"])
    if "recordings" in report:
        _print_recordings(report["recordings"])
    if "stature" in report:
        _print_stature(report["stature"])
    return 0


def _print_scenes(rep: dict) -> None:
    print(f"{'scenario':22} {'switches A/B':>12} {'found A/B with other':>21} {'A err alone':>11} {'with B':>7} "
          f"{'ratio':>6} {'B err alone':>11} {'with A':>7} {'ratio':>6} {'B dev':>6} {'ms/frame 2p':>11} {'1p':>6} "
          f"{'passes':>6}")
    for r in rep["scenarios"]:
        e, b = r["a_error_px"], r["b_error_px"]
        print(f"{r['scenario']:22} {r['identity_switches']['a']:>5} / {r['identity_switches']['b']:<4} "
              f"{r['found']['a_both']:>9.2f} / {r['found']['b_both']:<9.2f} {e['alone']:>11} {e['with_b']:>7} "
              f"{e['ratio']!s:>6} {b['alone']!s:>11} {b['with_a']!s:>7} {b['ratio']!s:>6} "
              f"{r['b_deviation_from_alone_px']!s:>6} {r['ms_per_frame']['two_people']:>11} "
              f"{r['ms_per_frame']['a_alone']:>6} {r['landmark_passes_per_frame']:>6}")
    print(f"\n{'hidden by the other':22} {'A: share':>9} {'vis hidden/seen':>15} {'ratio seen':>10} "
          f"{'B: share':>9} {'vis hidden/seen':>15} {'ratio seen':>10} {'flexion vs alone A/B':>20} "
          f"{'fall msgs 2p/alone':>18}")
    for r in rep["scenarios"]:
        cells = []
        for who in ("a", "b"):
            h, e = r[f"{who}_hidden"], r[f"{who}_error_seen_px"]
            cells.append(f"{h['share']!s:>9} {h['visibility_hidden']!s:>7} / {h['visibility_seen']!s:<5} "
                         f"{e['ratio']!s:>10}")
        flex, falls = r["flexion_vs_alone_deg"], r["fall_messages"]
        cells.append(f"{flex['a']!s:>11} / {flex['b']!s:<6} {falls['with_both']:>9} / "
                     f"{falls['a_alone'] + falls['b_alone']:<6}")
        print(f"{r['scenario']:22} {' '.join(cells)}")
    for kind, c in rep.get("summary", {}).items():
        where = "in front of" if kind == "front" else "behind"
        print(f"B {where} A, {c['crossings']} crossings: the hidden person within 1.2x on {c['hidden_within_1_2']}, "
              f"the one in front on {c['in_front_within_1_2']}; at most one "
              f"switch each on {c['at_most_one_switch_each']}, none on {c['without_switch']}")
        if "with_fall_messages" in c:
            m = c["flexion_vs_alone_deg_median"]
            print(f"  fall messages on {c['with_fall_messages']} crossings, raised by the other's presence on "
                  f"{c['raised_by_the_other']} ({c['fall_messages_alone']} messages alone); the "
                  f"fit's flexions off their value alone by a median {m['hidden']} deg (hidden), {m['in_front']} "
                  "deg (in front)")


def _print_falls(rep: dict) -> None:
    where = "between the camera and the faller" if rep["kneel_at"] == "camera" else "at the faller's side"
    print(f"\nfalls with a bystander ({rep['split']} scenarios, real fit, geometry {rep['geometry']}; kneeling "
          f"{where}; landmarks hidden by the other person: "
          f"{'moved as measured' if rep['occlusion'] else 'not modelled'})")
    w = rep["with_bystander"]
    if "faller_frames_with_both" in w:
        print(f"the faller partly hidden by the bystander on {w['faller_frames_partly_hidden']} of "
              f"{w['faller_frames_with_both']} frames with both in view, in {w['cases_faller_partly_hidden']} scenarios; "
              f"not found for it on {w['faller_frames_lost']}")
    for part, c in rep["faller_3d_same_frames_mm"].items():
        what = "some landmark covered by the bystander's body" if part == "covered" else "none covered"
        print(f"the faller's 3D error (PA-MPJPE, 12 joints) on the {c['frames']} frames with {what} that both runs "
              f"fitted: {c['with_bystander']} mm with the bystander, {c['alone']} mm alone")
    print(f"{'':18} {'falls':>5} {'recall':>6} {'adl':>4} {'false':>5} {'bystander ev':>12} {'2nd ev':>6} "
          f"{'ended':>5} {'id switches':>11} {'median lat s':>12}")
    rows = [("alone", rep["alone"]), ("with a bystander", rep["with_bystander"])]
    rows += [(f"  {k}", v) for k, v in rep["per_bystander"].items()]
    for name, s in rows:
        print(f"{name:18} {s['falls']:>5} {s['recall']!s:>6} {s['adl']:>4} {s['false_alarms']:>5} "
              f"{s['bystander_events']:>12} {s['second_events']:>6} {s['ended']:>5} {s['identity_switches']:>11} "
              f"{s['median_latency_s']!s:>12}")
    ok = all(rep["with_bystander"][k] == rep["alone"][k] for k in ("recall", "false_alarms")) and not any(
        rep["with_bystander"][k] for k in ("second_events", "ended", "bystander_events"))
    print("target (recall and false alarms as alone, no second event, none ended, none for the bystander): "
          + ("met" if ok else "MISSED"))
    w = rep["with_bystander"]
    if "cases" in w:
        print(f"who is who (the faller the household's member, by height): faller recognised in "
              f"{w['faller_as_member']}/{w['cases']} scenarios, bystander as a visitor in "
              f"{w['bystander_as_visitor']}/{w['cases']}, bystander taken for the member in {w['bystander_as_member']}; "
              f"history on the faller in {w['history_on_faller_frames']}/{w['faller_in_view_frames']} frames with "
              f"them in view, on the bystander in {w['history_on_bystander_frames']}")


def _print_recordings(reps: dict) -> None:
    for geometry, rep in reps.items():
        print(f"\nreal recordings with a real bystander ({rep['folder']}, geometry {geometry})")
        for mode in ("alone", "with_bystander"):
            s = rep[mode]
            print(f"{mode:15} falls {s['detected']}/{s['falls']}, false alarms {s['false_alarms']}/{s['adl']}, "
                  f"bystander events {s['bystander_events']}, second events {s['second_events']}")


def _print_stature(rep: dict) -> None:
    print("\nshoulder height from one real image (pose2sim balancing, both feet down) against triangulated")
    for v in rep["views"]:
        print(f"{v['view']}: camera {v['camera_height_m']} m high, {v['tilt_deg']} deg down, {v['frames']} frames: "
              f"{v['shoulder_m']} m against {v['truth_m']} m (error {v['error_m']} m; stature {v['stature_m']} m)")
    print(f"spread between the views {rep['spread_between_views_m']} m, mean error {rep['mean_error_m']} m")
