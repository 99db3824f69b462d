"""BlazePose's world landmarks for the falls scenarios: what the daemon's landmark stage hands the fit with every
frame (issue 38 item 1), simulated from each scenario's true joints with the error model of :mod:`bench.world_sim`
(measured on real video with motion-capture truth: median PA-MPJPE 77 mm, the depth sign of 21 % of limb
segments wrong, gross failures on 4.5 % of the frames). ``posed bench falls --world`` fits with them; without
it the scenarios' fit has the 2D landmarks only, as a recording from another extractor has."""

from __future__ import annotations

import zlib

import numpy as np

from posed.bench.mocap_landmarks import BODY12
from posed.bench.world_sim import simulate_world

MEANING = ("simulated BlazePose world landmarks with every frame (bench.world_sim's error model, measured on real "
           "video: median PA-MPJPE 77 mm, 21 % of limb depth signs wrong, 4.5 % gross failures), as the daemon's "
           "landmark stage gives the fit")


def case_world(case) -> list[np.ndarray | None]:
    """Per frame of ``case`` (:class:`bench.falls.Case`), its world landmarks: 33 x 5 ``[x, y, z, visibility,
    presence]``, metres, mid-hip origin, the camera's axes (x right, y down, z forward, as MediaPipe's world
    axes), NaN outside the 12 body landmarks; None where the frame has no 2D landmarks (nobody in view). The
    error stream is seeded by the case's name, so a case gets the same stream on every run."""
    cam = case.camera
    truth = np.array([[cam.to_camera(fr.joints_world[name]) for name in BODY12] for fr in case.frames])
    truth -= 0.5 * (truth[:, 6:7] + truth[:, 7:8])            # BODY12: 6, 7 are the hips
    times = np.array([fr.t for fr in case.frames])
    fps = 1.0 / float(np.median(np.diff(times))) if len(times) > 1 else 10.0
    world = simulate_world(truth, fps, np.random.default_rng([zlib.crc32(case.name.encode()), 77]))
    return [w if fr.landmarks is not None else None for w, fr in zip(world, case.frames, strict=True)]
