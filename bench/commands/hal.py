"""hal throughput: squat-video decode, RGB-D .db3 write/playback, recording, real-time pacing.

Run: ``posed bench hal [--json] [--video PATH]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from posed import hal
from posed.camera_model import Intrinsics
from posed.daemon.preflight import SQUAT_VIDEO, shared_data


def _drain(src: hal.Source) -> int:
    n = 0
    while True:
        try:
            src.read(5.0)
            n += 1
        except hal.EndOfStream:
            return n


def measure(video: Path | None = None, repeats: int = 5) -> dict[str, float]:
    """Decode, .db3 and recording speeds on ``video`` (default: the squat video)."""
    from posed.hal import Db3Writer  # not at import: `posed` imports every bench module to list it

    video = shared_data() / SQUAT_VIDEO if video is None else video
    out: dict[str, float] = {}
    rates = []
    for _ in range(repeats):
        with hal.open_source(f"file:{video}?realtime=false") as s:
            t = time.perf_counter()
            n = _drain(s)
            rates.append(n / (time.perf_counter() - t))
    out["squat_decode_hal_fps"] = round(statistics.median(rates), 1)
    rates = []
    for _ in range(repeats):
        cap = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
        t = time.perf_counter()
        n = 0
        while cap.read()[0]:
            n += 1
        rates.append(n / (time.perf_counter() - t))
        cap.release()
    out["squat_decode_opencv_fps"] = round(statistics.median(rates), 1)

    cap = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
    frames = [cv2.resize(cap.read()[1][280:1000], (640, 480)) for _ in range(30)]
    cap.release()
    k = Intrinsics(615.0, 615.0, 319.5, 239.5, 640, 480)
    kd = Intrinsics(385.0, 385.0, 319.5, 239.5, 640, 480)
    yy, xx = np.mgrid[0:480, 0:640]
    depth = (2000 + 500 * np.sin(xx / 50.0) + 300 * np.cos(yy / 40.0)).astype(np.uint16)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        raw_pose = ((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), (0.015, 0.0, 0.0))
        for name, depth_k, pose in (("prealigned", k, None), ("raw", kd, raw_pose)):
            path = d / f"{name}.db3"
            w = Db3Writer(path, k, 30, depth_scale=0.001, depth_intrinsics=depth_k, depth_to_colour=pose)
            t = time.perf_counter()
            for i, im in enumerate(frames):
                w.write(im, depth, i * 33.333, i)
            w.close()
            out[f"db3_write_{name}_ms_per_frame"] = round((time.perf_counter() - t) / len(frames) * 1000, 2)
            out[f"db3_{name}_MB_per_frame"] = round(path.stat().st_size / len(frames) / 1e6, 3)
            rates = []
            for _ in range(3):
                with hal.open_source(f"file:{path}?realtime=false") as s:
                    t = time.perf_counter()
                    n = _drain(s)  # includes the <= 50 ms end-of-file detection
                    rates.append(n / (time.perf_counter() - t))
            out[f"db3_playback_{name}_fps"] = round(statistics.median(rates), 1)
        folder = d / "images"
        folder.mkdir()
        for i, im in enumerate(frames):
            cv2.imwrite(str(folder / f"{i:03d}.png"), im)
        for suffix in (".mkv", ".avi", ".mp4"):
            with hal.open_source(f"file:{folder}?realtime=false") as s:
                t = time.perf_counter()
                summary = hal.record(s, str(d / f"rec{suffix}"))
                out[f"record_640x480{suffix}_ms_per_frame"] = round((time.perf_counter() - t) / summary.frames
                                                                    * 1000, 2)
    late = []
    with hal.open_source(f"file:{video}") as s:
        for _ in range(10):
            f = s.read(2.0)
            late.append((time.monotonic() - f.t) * 1000.0)
    out["realtime_lateness_ms_median"] = round(statistics.median(late), 2)
    out["realtime_lateness_ms_max"] = round(max(late), 2)
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--video", type=Path, default=None, help="video to decode (default: the squat video)")


def run(args: argparse.Namespace) -> int:
    result = measure(args.video)
    if getattr(args, "json", False):
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:40s} {value}")
    return 0
