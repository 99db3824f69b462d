"""A scaled-down RGB-D frame through ``posed run`` (the .db3 the hal tests make from the real squat video, with a
working size of a quarter of its pixels so that the capture stage halves colour and depth): the landmarks
topic reports the source's pixels, and the depth at each landmark is exactly what the landmark stage sampled on
the halved depth at the halved landmark positions."""

from __future__ import annotations

import numpy as np
import pytest

from posed import hal
from posed.landmarks import sample_depth
from tests.daemon.replay_util import replay_to_end
from tests.hal.conftest import DB3_FRAMES


@pytest.mark.timeout(300)
def test_scaled_rgbd_frames_keep_depth_and_landmarks_consistent(tmp_path, squat_db3):
    frames = []
    with hal.open_source(hal.SourceConfig(type="file", path=str(squat_db3.path), realtime=False)) as src:
        for _ in range(DB3_FRAMES):
            frames.append(src.read(5.0))
    w, h = frames[0].width, frames[0].height
    got = replay_to_end(tmp_path, squat_db3.path, "rgbd2", ("landmarks", "status"),
                        f"pipeline.frame_max_pixels={(w // 2) * (h // 2)}")
    msgs = sorted(got["landmarks"], key=lambda m: m["seq"])
    assert [m["seq"] for m in msgs] == list(range(DB3_FRAMES))
    cams = [s["camera"] for s in got["status"] if "scale" in s["camera"]]
    assert cams and (cams[-1]["scale"], cams[-1]["working_width"], cams[-1]["working_height"]) == (2, w // 2, h // 2)
    for m, f in zip(msgs, frames, strict=True):
        assert m["image_size"] == [w, h]
        lms = np.array([[np.nan] * 5 if lm is None else lm for lm in m["landmarks"]], dtype=np.float64)
        assert np.nanmax(lms[:, 1]) > h // 2              # source pixels (the person reaches below the middle)
        working = lms.copy()
        working[:, :3] /= 2
        depth = np.array([np.nan if v is None else v for v in m["depth_m"]], dtype=np.float64)
        assert np.array_equal(depth, sample_depth(hal.downscale_depth(f.depth, 2), f.depth_scale, working),
                              equal_nan=True)
        assert np.isfinite(depth).sum() > 20
