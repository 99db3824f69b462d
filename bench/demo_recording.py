"""The generated demo input used when the real squat video is not available: a landmark recording of
``bench.simulate``'s squat motion (three squats, 10 fps, 640x480, pinhole camera 3 m away, 1 px noise)."""

from __future__ import annotations

from pathlib import Path

FPS = 10.0
IMAGE_SIZE = (640, 480)
REPEATS = 3
SEED = 7


def ensure_demo_recording(path: Path) -> Path:
    """Write the recording to ``path`` unless it is already there; returns ``path``."""
    if path.is_file():
        return path
    from posed.bench import simulate
    from posed.landmarks import LandmarkFrame, RecordingHeader, write_recording

    camera = simulate.LevelCamera(model="pinhole", distance_m=3.0)
    seq = simulate.sequence("squat")
    frames = []
    t_offset = 0.0
    for rep in range(REPEATS):
        rendered = simulate.render_sequence(seq, fps=FPS, seed=SEED + rep, camera=camera, image_size=IMAGE_SIZE,
                                            noise_px=1.0)
        for t, landmarks, _pose in rendered[(1 if rep else 0):]:
            frames.append(LandmarkFrame(len(frames), round(t_offset + t, 4), landmarks))
        t_offset += seq.duration_s
    header = RecordingHeader(IMAGE_SIZE, FPS, source="posed demo: bench.simulate squat x3",
                             camera=camera.intrinsics(IMAGE_SIZE))
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    write_recording(tmp, header, frames)
    tmp.replace(path)
    return path
