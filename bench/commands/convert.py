"""Converter accuracy: the ONNX models against the exact result, with LiteRT as the yardstick, output by output.

The criterion (bench/convert_equivalence.py, docs/models.md): onnxruntime's error against the exact
(float64) result within 1e-3 + 2e-5 x max|exact| and no worse than 1.5 x the worse LiteRT kernel set. The
difference to LiteRT itself (the old 1e-3 target) is shown for information. For each model and input (real images of the shared test data and uniform noise) and each output the ONNX
model keeps: max |onnxruntime - LiteRT| for LiteRT's built-in kernels and its XNNPACK delegate, LiteRT's own
XNNPACK-vs-built-in difference (float32's reproducibility on that output), the largest |value|, and the error
of each of the three against the exact result (the converted graph evaluated in float64). LiteRT
(``ai-edge-litert``) comes with the test extra: ``pip install -e '.[test]'``.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict

TARGET = 1e-3
SQUAT_FRAMES = (0, 16, 32, 48, 64)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--random", type=int, default=4, metavar="N", help="random inputs per model (default 4)")
    parser.add_argument("--no-exact", action="store_true", help="skip the float64 evaluation (~1 s per input)")
    parser.add_argument("--models-dir", metavar="DIR", help="models folder (default: as `posed models where`)")


def _real_inputs() -> dict:
    """pose.jpg, the sitting image and every 16th frame of the squat video (BGR), from the shared test data."""
    from posed.bench import conformance
    from posed.daemon.preflight import shared_data

    root = shared_data()
    images = {ref.name: ref.image for ref in (conformance.pose_jpg(root), conformance.sitting(root))}
    frames, _ = conformance.squat_video(root)
    images.update({f"squat frame {i}": frames[i] for i in SQUAT_FRAMES})
    return images


def run(args: argparse.Namespace) -> int:
    try:
        import ai_edge_litert  # noqa: F401
        import onnx
        import onnxruntime as ort

        from posed.bench.convert_equivalence import (
            ExactModel,
            diff_outputs,
            litert_outputs,
            model_input,
            random_input,
        )
    except ImportError as exc:
        print(f"posed bench convert: {exc.name} is not installed; it needs the test extra: "
              "pip install -e '.[test]'", file=sys.stderr)
        return 2
    from posed.landmarks import ModelMissingError, default_models_dir, find_models

    try:
        paths = find_models(default_models_dir(args.models_dir or ""))
        images = _real_inputs()
    except (ModelMissingError, FileNotFoundError) as exc:
        print(f"posed bench convert: {exc}", file=sys.stderr)
        return 2

    rows = []
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    for model, onnx_path, tflite_path in (("pose_detection", paths.detector_onnx, paths.detector_tflite),
                                          ("pose_landmark_full", paths.landmark_onnx, paths.landmark_tflite)):
        session = ort.InferenceSession(str(onnx_path), opts, providers=["CPUExecutionProvider"])
        exact = None if args.no_exact else ExactModel(onnx.load(str(onnx_path)))
        inputs = {name: model_input(image, model) for name, image in images.items()}
        inputs.update({f"random {seed}": random_input(model, seed) for seed in range(args.random)})
        for source, x in inputs.items():
            names = [o.name for o in session.get_outputs()]
            got = dict(zip(names, session.run(names, {session.get_inputs()[0].name: x}), strict=True))
            for d in diff_outputs(got, litert_outputs(tflite_path, x, "built-in"),
                                  litert_outputs(tflite_path, x, "XNNPACK"), None if exact is None else exact(x)):
                rows.append({"model": model, "input": source, **asdict(d), "within_target": d.worst <= TARGET,
                             "litert_within_target": d.litert_spread <= TARGET,
                             "equivalent": None if exact is None else d.equivalent,
                             "exact_bound": None if exact is None else d.exact_bound,
                             "litert_bound": None if exact is None else d.litert_bound})
    missed = [r for r in rows if not r["within_target"]]
    report = {"target_abs": TARGET, "rows": rows, "pairs": len(rows), "pairs_within_target": len(rows) - len(missed),
              "missed_where_litert_itself_misses": sum(not r["litert_within_target"] for r in missed),
              "exact_within_target": None if args.no_exact else {
                  impl: sum(r["exact_error"][impl] <= TARGET for r in rows) for impl in ("onnx", "built-in", "XNNPACK")},
              "pairs_equivalent": None if args.no_exact else sum(r["equivalent"] for r in rows),
              "versions": {"onnxruntime": ort.__version__, "onnx": onnx.__version__}}
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_table(report)
    return 0


def _print_table(report: dict) -> None:
    print("| model | input | output | onnx vs built-in | onnx vs XNNPACK | LiteRT spread | max abs value | "
          "error vs float64: onnx / built-in / XNNPACK | criterion | 1e-3 of LiteRT |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in report["rows"]:
        exact = r["exact_error"]
        ex = "" if exact is None else f"{exact['onnx']:.1e} / {exact['built-in']:.1e} / {exact['XNNPACK']:.1e}"
        mark = "yes" if r["within_target"] else "no" + ("" if r["litert_within_target"] else " (LiteRT too)")
        crit = "" if r["equivalent"] is None else ("met" if r["equivalent"] else "MISSED")
        print(f"| {r['model']} | {r['input']} | {r['output']} | {r['onnx_vs_builtin']:.1e} | "
              f"{r['onnx_vs_xnnpack']:.1e} | {r['litert_spread']:.1e} | {r['max_abs_value']:.3g} | {ex} | {crit} | "
              f"{mark} |")
    print(f"\n{report['pairs_within_target']} of {report['pairs']} (input, output) pairs within "
          f"{report['target_abs']:g} of both LiteRT kernel sets; of the others, "
          f"{report['missed_where_litert_itself_misses']} are where LiteRT's own two kernel sets also differ by "
          f"more than {report['target_abs']:g}.")
    if report["pairs_equivalent"] is not None:
        print(f"Equivalence criterion (error vs float64 <= 1e-3 + 2e-5 max|exact| and <= 1.5 x the worse LiteRT "
              f"kernel set): met on {report['pairs_equivalent']} of {report['pairs']} pairs.")
    if report["exact_within_target"]:
        within = ", ".join(f"{impl} {n}" for impl, n in report["exact_within_target"].items())
        print(f"Within {report['target_abs']:g} of the exact (float64) result, of {report['pairs']} pairs: {within}.")
