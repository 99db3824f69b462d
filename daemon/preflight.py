"""Checks before anything is started, each problem with its fix; and the embedded default input.

``source.path`` empty (``type: file``) means the embedded demo input: the real squat video of the shared test
data (tfjs-models' ``pose_squats.mp4``) when it is there, else a landmark recording the project generates
(``bench.simulate``'s squat sequence) in the cache dir.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

from daemon.config import Config
from hal import is_landmark_recording

ROOT = Path(__file__).resolve().parent.parent
SQUAT_VIDEO = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"


def shared_data() -> Path:
    return Path(os.environ.get("POSED_SHARED_DATA", ROOT.parent / "shared" / "data"))


def cache_dir() -> Path:
    base = os.environ.get("CACHE_DIRECTORY") or os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base.split(":")[0]) / "posed"


def default_input(make_recording: Callable[[Path], Path]) -> Path:
    """The embedded demo input: the real squat video if present, else the landmark recording that
    ``make_recording(path)`` writes (the CLI passes ``bench.demo_recording.ensure_demo_recording``: the
    daemon itself never loads the offline package)."""
    video = shared_data() / SQUAT_VIDEO
    if video.is_file():
        return video
    return make_recording(cache_dir() / "demo_squats.landmarks.jsonl")


def resolve_source(cfg: Config, make_recording: Callable[[Path], Path]) -> Config:
    """``cfg`` with an empty file path replaced by the embedded demo input."""
    if cfg.source.type != "file" or cfg.source.path:
        return cfg
    return dataclasses.replace(cfg, source=dataclasses.replace(cfg.source, path=str(default_input(make_recording))))


def check(cfg: Config) -> list[str]:
    """Every problem that would stop the daemon at once, each naming what to change."""
    problems: list[str] = []
    src = cfg.source
    if src.type == "file" and not Path(src.path).exists():
        problems.append(f"source.path: {src.path} does not exist; give a video, an image folder, a RealSense "
                        "recording or a .landmarks.jsonl (or --source file:PATH)")
    if cfg.zenoh.config_file and not Path(cfg.zenoh.config_file).is_file():
        problems.append(f"zenoh.config_file: {cfg.zenoh.config_file} does not exist; give a Zenoh JSON5 "
                        "config or leave it empty")
    if not (src.type == "file" and is_landmark_recording(src.path)):
        from landmarks import ModelMissingError, find_models

        try:
            find_models(cfg.landmarks.models_dir or None)
        except ModelMissingError as exc:
            text = str(exc)
            if "posed models fetch" not in text:
                text += "; run: posed models fetch"
            problems.append(f"landmarks: {text}")
    return problems
