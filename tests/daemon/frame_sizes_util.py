"""Run ``posed run`` on a source to its end (``bench.clips.run_to_end``: a Zenoh router on 127.0.0.1 with
subscribers on pose, landmarks, status and fall events, an sd_notify socket read like systemd); and real clips
made with cv2.VideoWriter from the shared test footage (other sizes and frame rates)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from posed.bench.clips import Run, frames_taken
from posed.bench.clips import run_to_end as _run_to_end

ROOT = Path(__file__).resolve().parents[2]

__all__ = ["ROOT", "Run", "frames_taken", "read_frames", "run_to_end", "write_video"]


def run_to_end(tmp_path: Path, source: str, *overrides: str, robot: str = "fs", timeout_s: float = 150.0) -> Run:
    """``posed run --source SOURCE`` from the checkout (paced unless an override says otherwise) to its end."""
    return _run_to_end(tmp_path, source, *overrides, robot=robot, timeout_s=timeout_s, cwd=ROOT)


def read_frames(path: Path, n: int | None = None, step: int = 1) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    frames = []
    i = 0
    while n is None or len(frames) < n:
        ok, image = cap.read()
        if not ok:
            break
        if i % step == 0:
            frames.append(image)
        i += 1
    cap.release()
    return frames


def write_video(path: Path, frames: list[np.ndarray], fps: float) -> Path:
    """An MJPG AVI of ``frames`` at ``fps`` (what a webcam or a CCTV export gives)."""
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert vw.isOpened(), f"OpenCV cannot write {path}"
    for f in frames:
        assert f.shape[:2] == (h, w)
        vw.write(f)
    vw.release()
    return path
