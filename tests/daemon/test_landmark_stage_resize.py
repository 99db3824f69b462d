"""The landmark stage across a change of frame size mid-stream (a camera replugged at another resolution):
the tracked region of interest is in the old frame's pixels, so the stage forgets it (as after a restart of
the source) and the first frame of the new size runs the detector and finds the person. Before, that frame
had no person (quarter size, or larger: the landmark model looked at a region of the old size) and the next
one recovered, or (half size) landmarks off the person.

The real stage loop (``daemon.stages.landmark.run``) with the real BlazePose models on real frames (the squat
video, then the same frames at other sizes), behind a stand-in for the stage runtime (no processes, no
shared memory)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from posed.daemon.config import load_config
from posed.daemon.messages import FrameRef
from posed.daemon.stages.base import StageStop
from posed.daemon.stages.landmark import run
from tests.daemon.fakes import RecordingLog

SQUAT = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"


def _frames(shared_data: Path, n: int) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(shared_data / SQUAT), cv2.CAP_FFMPEG)
    frames = []
    while len(frames) < n:
        ok, image = cap.read()
        assert ok, "the squat video ended early"
        frames.append(image)
    cap.release()
    return frames


class _Inbox:
    def __init__(self, refs: list[FrameRef]) -> None:
        self.refs = list(refs)

    def wait(self, timeout: float):
        return self.refs.pop(0) if self.refs else None


class _Ring:
    """Hands out the image each FrameRef names (by seq)."""

    def __init__(self, images: dict[int, np.ndarray]) -> None:
        self.images = images

    def read(self, ref: FrameRef):
        return self.images[ref.seq].copy(), None, 0.0


class _Runtime:
    """What ``landmark.run`` uses of a StageRuntime; it stops once every frame was taken."""

    def __init__(self, config, refs: list[FrameRef], images: dict[int, np.ndarray]) -> None:
        self.config = config
        self.input = _Inbox(refs)
        self.ring = _Ring(images)
        self.log = RecordingLog()
        self.sent = []
        self.errors = 0

    def step(self):
        return contextlib.nullcontext()

    def ready(self) -> None:
        pass

    def beat(self) -> None:
        pass

    def check_stop(self) -> None:
        if not self.input.refs:
            raise StageStop

    def drop(self) -> None:
        raise AssertionError("no frame is dropped here")

    def error(self) -> None:
        self.errors += 1

    def send(self, message, lossless: bool = False) -> None:
        self.sent.append(message)

    def done(self, *a) -> None:
        pass

    def fatal(self, message: str, fix: str = "") -> None:
        raise AssertionError(f"{message} ({fix})")


def _run_stage(frames: list[np.ndarray], max_people: int) -> list:
    """The stage on ``frames`` (any sizes) as consecutive frames of one stream; the LandmarkMsgs it sent."""
    config = load_config(None, overrides=[f"landmarks.max_people={max_people}"])
    refs, images = [], {}
    for seq, image in enumerate(frames):
        h, w = image.shape[:2]
        refs.append(FrameRef(slot=0, seq=seq, t_capture=seq / 30.0, width=w, height=h, has_depth=False))
        images[seq] = image
    rt = _Runtime(config, refs, images)
    with pytest.raises(StageStop):
        run(rt)
    assert rt.errors == 0, rt.log.lines
    assert [m.frame.seq for m in rt.sent] == list(range(len(frames)))
    return rt.sent


@pytest.mark.parametrize("max_people", [1, 3])
@pytest.mark.parametrize("new_size", [(180, 320), (360, 640), (1080, 1920)], ids=["quarter", "half", "larger"])
def test_the_first_frame_after_a_size_change_finds_the_person(shared_data, max_people, new_size):
    frames = _frames(shared_data, 12)          # 720x1280 (portrait)
    h, w = frames[0].shape[:2]
    before = frames[:8]
    after = [cv2.resize(f, new_size, interpolation=cv2.INTER_AREA) for f in frames[8:]]
    sent = _run_stage(before + after, max_people)
    found = [m.frame.landmarks is not None for m in sent]
    print("person found per frame:", found)
    assert all(found[:8]), found                              # followed at the first size
    assert all(found[8:]), found                              # the first frame at the new size too
    first = sent[8]
    assert first.image_size == new_size
    lms = first.frame.landmarks
    visible = lms[:, 3] > 0.5
    assert visible.sum() >= 10
    nw, nh = new_size                                         # on the person, in the new frame's pixels
    assert (lms[visible, 0] > -0.1 * nw).all() and (lms[visible, 0] < 1.1 * nw).all()
    assert (lms[visible, 1] > -0.1 * nh).all() and (lms[visible, 1] < 1.1 * nh).all()
    # and on the person: the hips where they were at the old size, in proportion to the frame (before the
    # fix, at half size, the old region of interest gave landmarks with the hips at (0.75, 1.07) of the frame)
    hip_old = sent[7].frame.landmarks[23:25, :2].mean(axis=0) / (w, h)
    hip_new = lms[23:25, :2].mean(axis=0) / new_size
    assert np.abs(hip_new - hip_old).max() < 0.05, (hip_old, hip_new)
