"""Landmark stage speed: onnxruntime (converted models) side by side with LiteRT (original .tflite).

Both back ends get the same input tensors, built from the frames of a real video (default: the squat video of
the shared test data): the detector's letterboxed frames and the landmark model's ROI crops from a tracking
run. Reported per thread count: milliseconds per call of each model (median), the ratio onnx/LiteRT, and the
whole stage per frame (crop, inference, decode, smoothing) in tracking mode and in detection mode (detector
every frame). The landmark model is timed as shipped (converted without the segmentation head, which posed
never reads) and, for comparison, converted in memory with all five outputs, as LiteRT runs it. LiteRT
(``ai-edge-litert``) comes with the test extra: ``pip install -e '.[test]'``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from posed.commands import add_config_args, config_from_args
from posed.daemon.preflight import SQUAT_VIDEO, shared_data

MEDIAPIPE_TRACKING_MS = 33.0  # MediaPipe 0.10.21's own pipeline, median per frame, tracking (measured once)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--video", metavar="PATH", help="video to take frames from (default: the squat video of "
                                                        "the shared test data, $POSED_SHARED_DATA)")
    parser.add_argument("--frames", type=int, default=65, help="frames of the video to use (default 65)")
    parser.add_argument("--passes", type=int, default=3, help="passes over the frames per measurement")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts to measure")
    parser.add_argument("--models-dir", metavar="DIR", help="models folder (default: landmarks.models_dir ...)")
    add_config_args(parser, source=False)


# -- LiteRT back end (the reference; same call interface as landmarks.runtime) ---------------------------------

class LiteRTDetector:
    def __init__(self, path: Path, threads: int) -> None:
        from ai_edge_litert.interpreter import Interpreter

        from posed.landmarks import DetectorOutputs

        self._outputs = DetectorOutputs
        self.interpreter = Interpreter(model_path=str(path), num_threads=threads)
        self.interpreter.allocate_tensors()
        self.input = self.interpreter.get_input_details()[0]["index"]
        by_shape = {tuple(d["shape"]): d["index"] for d in self.interpreter.get_output_details()}
        self.boxes, self.scores = by_shape[(1, 2254, 12)], by_shape[(1, 2254, 1)]

    def __call__(self, tensor: np.ndarray):
        self.interpreter.set_tensor(self.input, tensor)
        self.interpreter.invoke()
        return self._outputs(self.interpreter.get_tensor(self.boxes).reshape(2254, 12),
                             self.interpreter.get_tensor(self.scores).reshape(2254))


class LiteRTLandmarkModel:
    def __init__(self, path: Path, threads: int) -> None:
        from ai_edge_litert.interpreter import Interpreter

        from posed.landmarks import LandmarkOutputs

        self._outputs = LandmarkOutputs
        self.interpreter = Interpreter(model_path=str(path), num_threads=threads)
        self.interpreter.allocate_tensors()
        self.input = self.interpreter.get_input_details()[0]["index"]
        by_shape = {tuple(d["shape"]): d["index"] for d in self.interpreter.get_output_details()}
        self.idx = [by_shape[(1, 195)], by_shape[(1, 1)], by_shape[(1, 64, 64, 39)], by_shape[(1, 117)]]

    def __call__(self, tensor: np.ndarray):
        self.interpreter.set_tensor(self.input, tensor)
        self.interpreter.invoke()
        lms, flag, heatmap, world = (self.interpreter.get_tensor(i) for i in self.idx)
        return self._outputs(lms.reshape(195), float(flag.reshape(-1)[0]), heatmap[0], world.reshape(117))


def _landmark_model_full_graph(tflite: Path, onnx_path: Path, settings):
    """The landmark model converted with all five outputs, segmentation head included (in memory), for
    comparison with the shipped model, which leaves it out; None without the converter's packages."""
    try:
        from posed.landmarks.convert import convert
    except ImportError:
        return None
    from posed.landmarks import OnnxLandmarkModel

    full = convert(tflite.read_bytes(), tflite.stem)
    return OnnxLandmarkModel(onnx_path, settings, model=full.SerializeToString())


# -- measurement helpers --------------------------------------------------------------------------------------

def _read_frames(path: Path, limit: int) -> list[tuple[float, np.ndarray]]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    frames = []
    while len(frames) < limit:
        ok, image = cap.read()
        if not ok:
            break
        frames.append((cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0, image))
    cap.release()
    return frames


def _time_calls(runners: dict, inputs: list[np.ndarray], passes: int) -> dict[str, float]:
    """Median ms per call of each runner. Each pass runs every runner over all inputs in turn (a block per
    runner, so one back end's idle threads spinning down do not land in the other's time), and the passes
    alternate the order, so both see the same machine load on average."""
    for run in runners.values():
        run(inputs[0])
    times: dict[str, list[float]] = {name: [] for name in runners}
    names = list(runners)
    for p in range(passes):
        for name in names if p % 2 == 0 else reversed(names):
            run = runners[name]
            for x in inputs:
                t0 = time.perf_counter()
                run(x)
                times[name].append((time.perf_counter() - t0) * 1e3)
    return {name: float(np.median(v)) for name, v in times.items()}


def _time_stages(landmarkers: dict, frames, passes: int, sim_fps: float) -> dict[str, dict]:
    """Whole stage per frame for each landmarker: wall time of ``process_full`` (median, p95) and the median of
    each step. Passes alternate between the landmarkers (order reversed every pass) like :func:`_time_calls`."""
    totals: dict[str, list[float]] = {name: [] for name in landmarkers}
    steps: dict[str, dict[str, list[float]]] = {name: {} for name in landmarkers}
    detector_frames = dict.fromkeys(landmarkers, 0)
    names = list(landmarkers)
    for p in range(passes):
        for name in names if p % 2 == 0 else reversed(names):
            landmarker = landmarkers[name]
            landmarker.reset()
            for seq, (_, image) in enumerate(frames):
                t0 = time.perf_counter()
                result = landmarker.process_full(image, seq / sim_fps, seq)
                totals[name].append((time.perf_counter() - t0) * 1e3)
                detector_frames[name] += result.detector_ran
                for k, v in result.timings_ms.items():
                    steps[name].setdefault(k, []).append(v)
    return {name: {"ms": float(np.median(totals[name])), "p95_ms": float(np.percentile(totals[name], 95)),
                   "steps_ms": {k: float(np.median(v)) for k, v in steps[name].items()},
                   "detector_runs_per_pass": detector_frames[name] / passes}
            for name in landmarkers}


def _ratio(a: float, b: float) -> float:
    return float(a / b) if b > 0 else math.nan


def run(args: argparse.Namespace) -> int:
    from posed.landmarks import (
        ModelMissingError,
        OnnxDetector,
        OnnxLandmarkModel,
        PoseLandmarker,
        SessionSettings,
        default_models_dir,
        detector_input,
        find_models,
        landmark_input,
    )

    try:
        import ai_edge_litert
    except ImportError:
        print("posed bench landmarks: LiteRT (ai-edge-litert) is not installed; it is the reference this "
              "benchmark compares with: pip install -e '.[test]'", file=sys.stderr)
        return 2
    config = config_from_args(args)
    try:
        paths = find_models(default_models_dir(args.models_dir or config.landmarks.models_dir))
    except ModelMissingError as exc:
        print(f"posed bench landmarks: {exc}", file=sys.stderr)
        return 2
    video = Path(args.video) if args.video else shared_data() / SQUAT_VIDEO
    frames = _read_frames(video, args.frames)
    if not frames:
        print(f"posed bench landmarks: no frames from {video} (give --video PATH)", file=sys.stderr)
        return 2

    # Same inputs for both back ends: the detector tensors of every frame and the crops of a tracking run.
    base = replace(config.landmarks, models_dir=str(paths.models_dir))
    probe = PoseLandmarker(base)
    det_inputs = [detector_input(image)[0] for _, image in frames]
    crops = []
    for seq, (_, image) in enumerate(frames):
        result = probe.process_full(image, seq / 30.0, seq)
        if result.roi is not None:
            crops.append(landmark_input(image, result.roi))
    if not crops:
        print(f"posed bench landmarks: nobody found in {video}; give a video with a person", file=sys.stderr)
        return 2

    report: dict = {
        "input": {"video": str(video), "frames": len(frames), "image_size": list(frames[0][1].shape[1::-1]),
                  "passes": args.passes},
        "machine": {"cpus": os.cpu_count(), "loadavg_1min": os.getloadavg()[0], "python": platform.python_version(),
                    "onnxruntime": __import__("onnxruntime").__version__,
                    "ai_edge_litert": getattr(ai_edge_litert, "__version__", "?")},
        "mediapipe_tracking_ms": MEDIAPIPE_TRACKING_MS,
        "threads": {},
    }
    for threads in args.threads:
        settings = SessionSettings(threads=threads)
        onnx_det = OnnxDetector(paths.detector_onnx, settings)
        onnx_lm = OnnxLandmarkModel(paths.landmark_onnx, settings)
        lite_det = LiteRTDetector(paths.detector_tflite, threads)
        lite_lm = LiteRTLandmarkModel(paths.landmark_tflite, threads)
        full = _landmark_model_full_graph(paths.landmark_tflite, paths.landmark_onnx, settings)

        lm_runners = {"onnx": onnx_lm, "litert": lite_lm}
        if full is not None:
            lm_runners["onnx_full_graph"] = full
        lm_ms = _time_calls(lm_runners, crops, args.passes)
        det_ms = _time_calls({"onnx": onnx_det, "litert": lite_det}, det_inputs, args.passes)
        entry: dict = {
            "landmark_model": {"onnx_ms": lm_ms["onnx"], "litert_ms": lm_ms["litert"],
                               "ratio": _ratio(lm_ms["onnx"], lm_ms["litert"])},
            "detector": {"onnx_ms": det_ms["onnx"], "litert_ms": det_ms["litert"],
                         "ratio": _ratio(det_ms["onnx"], det_ms["litert"])},
        }
        if full is not None:
            entry["landmark_model_full_graph"] = {
                "onnx_ms": lm_ms["onnx_full_graph"], "litert_ms": lm_ms["litert"],
                "ratio": _ratio(lm_ms["onnx_full_graph"], lm_ms["litert"])}

        cfg = replace(base, threads=threads)
        stages: dict = {}
        for mode, tracking in (("tracking", True), ("detection", False)):
            mode_cfg = replace(cfg, tracking=tracking)
            landmarkers = {"onnx": PoseLandmarker(mode_cfg, detector=onnx_det, landmark_model=onnx_lm),
                           "litert": PoseLandmarker(mode_cfg, detector=lite_det, landmark_model=lite_lm)}
            if full is not None and tracking:
                landmarkers["onnx_full_graph"] = PoseLandmarker(mode_cfg, detector=onnx_det, landmark_model=full)
            stages[mode] = _time_stages(landmarkers, frames, args.passes, 30.0)
            stages[mode]["ratio"] = _ratio(stages[mode]["onnx"]["ms"], stages[mode]["litert"]["ms"])
        entry["stage_per_frame"] = stages
        entry["targets"] = {
            "landmark_model_onnx_le_litert": entry["landmark_model"]["ratio"] <= 1.0,
            "stage_tracking_faster_than_mediapipe": stages["tracking"]["onnx"]["ms"] < MEDIAPIPE_TRACKING_MS,
        }
        report["threads"][str(threads)] = entry

    if args.json:
        print(json.dumps(report, indent=2))
    else:
        _print_table(report)
    return 0


def _print_table(report: dict) -> None:
    inp = report["input"]
    print(f"posed bench landmarks: {inp['frames']} frames of {inp['video']} ({inp['image_size'][0]}x"
          f"{inp['image_size'][1]}), {inp['passes']} passes, {report['machine']['cpus']} CPUs, load "
          f"{report['machine']['loadavg_1min']:.2f}; ms per call / per frame, median")
    print(f"{'threads':>7}  {'what':36s} {'onnx':>8} {'litert':>8} {'ratio':>6}")
    for threads, e in report["threads"].items():
        rows = [("landmark model", e["landmark_model"]), ("detector", e["detector"])]
        if "landmark_model_full_graph" in e:
            rows.append(("landmark model, with segmentation head", e["landmark_model_full_graph"]))
        for name, r in rows:
            print(f"{threads:>7}  {name:36s} {r['onnx_ms']:8.2f} {r['litert_ms']:8.2f} {r['ratio']:6.2f}")
        for mode, s in e["stage_per_frame"].items():
            print(f"{threads:>7}  {'whole stage, ' + mode:36s} {s['onnx']['ms']:8.2f} {s['litert']['ms']:8.2f} "
                  f"{s['ratio']:6.2f}")
            steps = ", ".join(f"{k} {v:.2f}" for k, v in s["onnx"]["steps_ms"].items())
            print(f"{'':>7}    onnx steps: {steps}")
            if "onnx_full_graph" in s:
                print(f"{'':>7}    onnx with the segmentation head: {s['onnx_full_graph']['ms']:.2f}")
        t = e["targets"]
        print(f"{'':>7}  targets: landmark model onnx <= LiteRT: {'met' if t['landmark_model_onnx_le_litert'] else 'MISSED'}"
              f"; tracking stage < MediaPipe {report['mediapipe_tracking_ms']:.0f} ms: "
              f"{'met' if t['stage_tracking_faster_than_mediapipe'] else 'MISSED'}")
