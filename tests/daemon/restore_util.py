"""Recordings and in-process plumbing for the tests of the fall alarm across a restart and without frames
(tests/daemon/test_restored_falls*.py, test_alarm_*_e2e.py).

Everything is cut from a real recording of shared/data: urfd_dev's urfd_04 (UR Fall Detection, camera 0,
MediaPipe Holistic landmarks), a real fall from standing: ``falling`` at 3.3 s (impact 3.3 s), ``on_floor`` at
4.3 s, and the recording ends 0.17 s later. Its first frame is the person standing, its last frame with
landmarks the person lying on the floor where they fell.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from posed.landmarks.recording import LandmarkFrame, read_recording, write_recording

URFD04 = Path("falls") / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
CAMERA = ("falls.camera_height_m=0.85",)     # labels.json of urfd_dev: the camera 0.85 m up, level


def urfd04(shared_data: Path):
    header, frames, problems = read_recording(shared_data / URFD04)
    assert not problems and len(frames) > 100
    return header, frames


def standing(frames) -> LandmarkFrame:
    return frames[0]


def lying(frames) -> LandmarkFrame:
    return [f for f in frames if f.landmarks is not None][-1]


def held(frame: LandmarkFrame, t0: float, seconds: float, fps: float = 30.0, seq0: int = 0,
         nobody: bool = False) -> list[LandmarkFrame]:
    """``frame`` held still from capture time ``t0`` for ``seconds`` (``nobody``: frames without a person)."""
    n = int(round(seconds * fps))
    return [replace(frame, seq=seq0 + i, t=round(t0 + i / fps, 6), landmarks=None if nobody else frame.landmarks)
            for i in range(n)]


def write(path: Path, header, frames: list[LandmarkFrame]) -> Path:
    write_recording(path, header, frames)
    return path


def config(*overrides: str):
    from posed.daemon.config.schema import load_config

    return load_config(None, overrides=[*CAMERA, *overrides])


def fitted(cfg, header, frames):
    """(frame, result, others) per frame, fitted as the fitting stage fits them."""
    from posed.commands.falls import fit_frames

    return list(fit_frames(cfg, header, frames))


def fit_msg(header, frame, result, others=()):
    from posed.daemon.messages import FitMsg

    return FitMsg(result, frame, frame.t, tuple(header.image_size), (), header.camera, others=tuple(others))
