"""Landmark stage: ``frames`` mailbox (FrameRef) -> pixels from the ring -> BlazePose -> ``landmarks`` mailbox.

Warm-up loads the models and runs them once (``PoseLandmarker.warmup``) before the stage reports ready. A
missing model is fatal (exit 78) with the landmark package's message, which names ``posed models fetch``.
A FrameRef whose slot was overwritten before it was read is dropped.

Depth: when the frame came with a depth image aligned to it (``FrameRef.has_depth``: a RealSense camera or
recording), the depth at each landmark (``landmarks.with_depth``, metres) goes to the fitting stage on the
frame itself, ``LandmarkMsg.frame.depth_m``; otherwise (no depth, or no person) ``depth_m`` is None.

Frame sizes: a frame the capture stage scaled down (``FrameRef.scale`` k > 1, hal.resize) is processed at its
working size, and its landmarks go on in the source's own pixels: x, y and z (pixels on the x scale) times k,
``image_size`` the source's size (``FrameRef.full_size``), the intrinsics the source's. So the fit, the fall
detector, the landmarks topic and a recording are the same as with the frame at full size, and ``posed
render`` draws them on the original video. The depth at the landmarks is sampled before, on the scaled depth.

A change of frame size mid-stream (a camera replugged at another resolution, a webcam switching mode) resets
the landmarker as a source that starts again does: its region of interest is in the old frame's pixels (the
landmark model would look at the wrong place: no person for a frame, or landmarks off the person), so the
first frame of the new size runs the detector (logged as ``frame_size_changed``).

Gravity: the camera accelerometer's down direction (``FrameRef.gravity``, hal.imu) goes on the frame too,
``LandmarkMsg.frame.gravity``, person or not: the fall detector's camera geometry follows it.

Several people (``landmarks.max_people`` > 1, default 3): :class:`landmarks.MultiPoseLandmarker` follows each
person with a landmark pass of their own; from the first frame with two people on, frames carry ``people``
(track ids, landmarks in the source's pixels; the depth at the landmarks is sampled for the frame's own person
only). The frame's own landmarks stay those of the person followed longest, so with one person in view every
output is what the one-person landmarker gives. ``landmarks.max_people: 1`` runs the one-person landmarker.

The floor: with a depth image (and ``falls.enabled`` and ``falls.floor_from_depth``), the floor plane is
measured in it about once a second of capture time (:mod:`daemon.stages.depth_floor`, the gravity as its prior)
and the latest goes on every frame as ``LandmarkMsg.frame.extra["floor"]``, person or not. A fit that raises
is counted (``floor_failures`` in the log) and the frame goes on without it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from posed.daemon import clock
from posed.daemon.messages import LandmarkMsg, origin
from posed.daemon.stages.base import StageRuntime
from posed.daemon.stages.depth_floor import DepthFloor


def run(rt: StageRuntime) -> None:
    from posed.landmarks import ModelMissingError, MultiPoseLandmarker, PoseLandmarker, with_depth

    with rt.step():
        try:
            cfg = rt.config.landmarks
            landmarker = MultiPoseLandmarker(cfg) if cfg.max_people > 1 else PoseLandmarker(cfg)
            landmarker.warmup()
        except ModelMissingError as exc:
            rt.fatal(str(exc), fix="run: posed models fetch")
    rt.ready()
    inbox = rt.input
    failures = 0
    falls_cfg = rt.config.falls
    floor = DepthFloor() if falls_cfg.enabled and falls_cfg.floor_from_depth else None
    floor_failures = 0
    last_seq: int | None = None
    last_size: tuple | None = None
    while True:
        rt.beat()
        rt.check_stop()
        ref = inbox.wait(0.1)
        if ref is None:
            continue
        with rt.step():
            t_in = clock.now()
            got = rt.ring.read(ref)
            if got is None:
                rt.drop()
                continue
            image, depth, depth_scale = got
            if last_seq is not None and ref.seq <= last_seq:
                landmarker.reset()        # the source started again: forget the tracked person
            size = frame_size(ref)
            if last_size is not None and size != last_size:
                landmarker.reset()        # another frame size (a camera replugged): the ROI is in the old pixels
                rt.log.info("frame_size_changed", seq=ref.seq, size=size, previous=last_size,
                            note="tracking started again: the detector runs on this frame")
            last_seq, last_size = ref.seq, size
            try:
                frame = with_depth(landmarker.process(image, ref.t_capture, ref.seq), depth, depth_scale)
                if ref.scale != 1:
                    frame = to_source_pixels(frame, ref.scale)
                if ref.gravity is not None:
                    frame = replace(frame, gravity=ref.gravity)
            except Exception as exc:  # one bad frame must not stop the pipeline
                failures += 1
                rt.error()
                if failures <= 3 or failures % 100 == 0:
                    rt.log.error("landmarks_failed", error=repr(exc), seq=ref.seq, failures=failures)
                landmarker.reset()
                continue
            try:
                if floor is not None and depth is not None:
                    floor.offer(depth, depth_scale, ref.intrinsics, ref.gravity, ref.t_capture)
                    field = floor.field(ref.t_capture)
                    if field is not None:
                        frame = replace(frame, extra={**frame.extra, "floor": field})
            except Exception as exc:  # the floor is an extra: the frame goes on without it
                floor_failures += 1
                rt.error()
                if floor_failures <= 3 or floor_failures % 100 == 0:
                    rt.log.error("floor_fit_failed", error=repr(exc), seq=ref.seq, floor_failures=floor_failures)
            t_out = clock.now()
            rt.send(LandmarkMsg(frame, ref.t_capture, ref.full_size, ref.intrinsics,
                                (("landmarks_in", t_in), ("landmarks_out", t_out)), ref.t_origin),
                    lossless=ref.t_origin is not None)
        rt.done(t_out - t_in, origin(ref), t_out)


def frame_size(ref) -> tuple[int, int, int, tuple[int, int]]:
    """What the tracked region of interest depends on: the frame's size in the ring, the factor it was scaled
    down by and the source's own size. When any of these changes mid-stream (a camera replugged or switched to
    another resolution) the landmarker's ROI, in the old frame's pixels, points at the wrong place: the next
    frame would find nobody, or landmarks where the person is not."""
    return (int(ref.width), int(ref.height), int(ref.scale), tuple(ref.full_size))


def to_source_pixels(frame, k: int):
    """``frame`` (a LandmarkFrame of an image scaled down by the whole factor ``k``) with its landmarks in the
    pixels of the source's image: x, y and z times ``k`` (visibility and presence as they are); so are the
    landmarks of each of its ``people``."""
    if frame.landmarks is None or k == 1:
        return frame

    def scaled(lms):
        lm = np.array(lms, dtype=np.float64, copy=True)
        lm[:, :3] *= float(k)
        return lm

    people = None if frame.people is None else tuple(replace(p, landmarks=scaled(p.landmarks))
                                                      for p in frame.people)
    return replace(frame, landmarks=scaled(frame.landmarks), people=people)
