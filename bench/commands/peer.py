"""Side by side with MediaPipe 0.10.21 itself: the same images (upright and rotated) and the squat video.

MediaPipe runs in its own virtual environment (it needs numpy<2), through ``_mediapipe_peer.py``; give its
Python with ``--mediapipe-python`` or ``$POSED_MEDIAPIPE_PYTHON``. Per image and rotation (0°, 90°, −90°, 180°,
``cv2.rotate``; the expectation rotated with it): error against the reference for posed and for MediaPipe
(max px over the compared landmarks, share within the tolerance) and posed against MediaPipe (all 33
landmarks). Both run in static-image mode on the images. Squat video: tracking mode, frames 1/30 s apart (as
the reference was made), 12 body landmarks, and the median time per frame of each.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from posed.commands import add_config_args, config_from_args

ROTATIONS = (0, 90, -90, 180)
PEER_SCRIPT = Path(__file__).with_name("_mediapipe_peer.py")
VENV_RECIPE = ("python3.11 -m venv /opt/mediapipe-peer && /opt/mediapipe-peer/bin/pip install "
               "mediapipe==0.10.21 'numpy<2'")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mediapipe-python", metavar="PATH", default=os.environ.get("POSED_MEDIAPIPE_PYTHON"),
                        help="Python of a venv with mediapipe==0.10.21 (default $POSED_MEDIAPIPE_PYTHON)")
    parser.add_argument("--no-video", action="store_true", help="images only")
    add_config_args(parser, source=False)


def _errors(found: np.ndarray | None, expected: np.ndarray, indices, tolerance: float) -> dict:
    if found is None:
        return {"found": False}
    err = np.linalg.norm(found[list(indices), :2] - expected[list(indices)], axis=1)
    return {"found": True, "max_px": float(err.max()), "mean_px": float(err.mean()),
            "within_tolerance": float(np.mean(err <= tolerance))}


def _apart(a: np.ndarray | None, b: np.ndarray | None, indices) -> dict | None:
    if a is None or b is None:
        return None
    d = np.linalg.norm(a[list(indices), :2] - b[list(indices), :2], axis=1)
    return {"max_px": float(d.max()), "mean_px": float(d.mean())}


def _run_peer(python: str, request: dict) -> dict:
    proc = subprocess.run([python, str(PEER_SCRIPT)], input=json.dumps(request), capture_output=True, text=True,
                          timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"MediaPipe peer failed ({python}, exit {proc.returncode}): {proc.stderr.strip()[-800:]}")
    return json.loads(proc.stdout)


def run(args: argparse.Namespace) -> int:
    from posed.bench import conformance
    from posed.daemon.preflight import shared_data
    from posed.landmarks import ModelMissingError, PoseLandmarker, rotate_image, rotate_points

    python = args.mediapipe_python
    if not python or not Path(python).is_file():
        print(f"posed bench peer: no MediaPipe Python given ({python!r}); make one with `{VENV_RECIPE}` and pass "
              "--mediapipe-python /opt/mediapipe-peer/bin/python (or set POSED_MEDIAPIPE_PYTHON)", file=sys.stderr)
        return 2
    config = config_from_args(args).landmarks
    root = shared_data()
    try:
        refs = [conformance.pose_jpg(root), conformance.sitting(root), conformance.coco_785(root)]
        static = PoseLandmarker(replace(config, tracking=False))
        tracking = PoseLandmarker(replace(config, tracking=True))
    except (FileNotFoundError, ModelMissingError) as exc:
        print(f"posed bench peer: {exc}", file=sys.stderr)
        return 2

    with tempfile.TemporaryDirectory(prefix="posed-peer-") as tmp:
        cases, request = [], {"images": [], "video": None if args.no_video else str(root / conformance.SQUAT_VIDEO)}
        for ref in refs:
            h, w = ref.image.shape[:2]
            for degrees in ROTATIONS:
                image = ref.image if degrees == 0 else rotate_image(ref.image, degrees)
                expected = ref.expected if degrees == 0 else rotate_points(ref.expected, degrees, w, h)
                name = f"{ref.name} {degrees}"
                path = Path(tmp) / f"{len(cases)}.png"  # lossless: both see the same pixels
                cv2.imwrite(str(path), image)
                request["images"].append({"name": name, "path": str(path)})
                cases.append((name, ref, image, expected, degrees))
        peer = _run_peer(python, request)

    report: dict = {"mediapipe": peer["mediapipe"], "images": [], "video": None}
    for name, ref, image, expected, degrees in cases:
        static.reset()
        ours = static.process_full(image, 0.0, 0).frame.landmarks
        theirs = None if peer["images"][name] is None else np.array(peer["images"][name], float)
        report["images"].append({
            "image": ref.name, "rotation": degrees, "reference": ref.source, "tolerance_px": ref.tolerance_px,
            "posed": _errors(ours, expected, ref.indices, ref.tolerance_px),
            "mediapipe": _errors(theirs, expected, ref.indices, ref.tolerance_px),
            "posed_vs_mediapipe_33": _apart(ours, theirs, range(33))})

    if peer["video"] is not None:
        frames, expected = conformance.squat_video(root)
        tracking.warmup()
        ours, times = [], []
        for seq, image in enumerate(frames):
            t0 = time.perf_counter()
            ours.append(tracking.process_full(image, seq / 30.0, seq).frame.landmarks)
            times.append((time.perf_counter() - t0) * 1e3)
        theirs = [None if f is None else np.array(f, float) for f in peer["video"]["frames"]]
        body = list(conformance.BODY)

        def per_frame(found):
            err = [np.linalg.norm(f[body, :2] - e[body, :2], axis=1) for f, e in zip(found, expected, strict=True)
                   if f is not None]
            return {"frames_found": len(err), "mean_px": float(np.mean(err)), "max_px": float(np.max(err))}

        apart = [_apart(a, b, body) for a, b in zip(ours, theirs, strict=True)]
        apart = [a for a in apart if a is not None]
        report["video"] = {
            "frames": len(frames), "posed": per_frame(ours), "mediapipe": per_frame(theirs),
            "posed_vs_mediapipe": {"mean_px": float(np.mean([a["mean_px"] for a in apart])),
                                   "max_px": float(np.max([a["max_px"] for a in apart]))},
            "posed_ms_median": float(np.median(times)), "mediapipe_ms_median": peer["video"]["median_ms"]}

    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_table(report)
    return 0


def _fmt(e: dict) -> str:
    if not e["found"]:
        return "not found"
    return f"{e['max_px']:.1f} px; {100 * e['within_tolerance']:.0f} %"


def _print_table(report: dict) -> None:
    print(f"MediaPipe {report['mediapipe']} vs posed; error against the reference: max px; share within the "
          "tolerance")
    print("| image | rotation | tolerance | posed | MediaPipe | posed vs MediaPipe, 33 landmarks (mean / max px) |")
    print("|---|---|---|---|---|---|")
    for r in report["images"]:
        apart = r["posed_vs_mediapipe_33"]
        ap = "" if apart is None else f"{apart['mean_px']:.1f} / {apart['max_px']:.1f}"
        print(f"| {r['image']} | {r['rotation']}° | {r['tolerance_px']:.1f} px | {_fmt(r['posed'])} | "
              f"{_fmt(r['mediapipe'])} | {ap} |")
    v = report["video"]
    if v:
        print(f"\nSquat video, {v['frames']} frames, tracking, 12 body landmarks against pose_squats.full.json: "
              f"posed mean {v['posed']['mean_px']:.2f} / max {v['posed']['max_px']:.1f} px "
              f"({v['posed']['frames_found']} frames found); MediaPipe mean {v['mediapipe']['mean_px']:.2f} / max "
              f"{v['mediapipe']['max_px']:.1f} px ({v['mediapipe']['frames_found']} found); posed vs MediaPipe mean "
              f"{v['posed_vs_mediapipe']['mean_px']:.2f} / max {v['posed_vs_mediapipe']['max_px']:.1f} px. "
              f"Median per frame: posed {v['posed_ms_median']:.1f} ms, MediaPipe {v['mediapipe_ms_median']:.1f} ms.")
