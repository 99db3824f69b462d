"""``posed render`` on a disk that fills up (exit 74, the folder named, no broken file left), a bad --hfov
(a usage error, not a traceback) and a fit file given as the input (named as such)."""

from __future__ import annotations

import numpy as np
import pytest

from posed.viz.video import VideoError, VideoOut
from tests.disk_full.conftest import posed


def test_render_on_a_full_disk_exits_74_and_leaves_no_file(tmpfs, short_fit):
    rec, fit = short_fit
    mnt = tmpfs("512k")
    out = mnt / "r.webm"
    r = posed("render", str(rec), "--fit", str(fit), "-o", str(out))
    # before: "12 frames -> r.webm", exit 0, and an empty or cut file
    assert r.returncode == 74, r.stderr
    assert f"disk full at {mnt}" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_a_video_the_writer_could_not_finish_is_found_at_close_and_removed(tmpfs, monkeypatch):
    """With the free-space check blinded, OpenCV's writer fails without a word: the count of the finished file
    catches it."""
    monkeypatch.setattr("posed.viz.video._free_bytes", lambda folder: None)
    out = tmpfs("256k") / "r.avi"
    rng = np.random.default_rng(0)
    with pytest.raises(VideoError, match="frames"):
        with VideoOut(out, 10.0, (320, 240)) as video:
            for _ in range(40):     # noise: about 40 kB a frame in Motion-JPEG, far more than the disk holds
                video.write(rng.integers(0, 256, (240, 320, 3), dtype=np.uint8))
    assert not out.exists()


def test_a_negative_hfov_is_a_usage_error(tmp_path, short_fit):
    rec, fit = short_fit
    r = posed("render", str(rec), "--fit", str(fit), "--hfov", "-5", "-o", str(tmp_path / "r.webm"))
    assert r.returncode == 2 and "--hfov" in r.stderr and "Traceback" not in r.stderr   # before: ValueError
    assert not (tmp_path / "r.webm").exists()


def test_a_fit_file_given_as_the_input_is_named_as_fit_results(tmp_path, short_fit):
    _, fit = short_fit
    r = posed("render", str(fit), "-o", str(tmp_path / "y.webm"))
    assert r.returncode == 2
    assert f"{fit} holds fit results; give the landmark recording it came from with --fit {fit}" in r.stderr
    assert "posed fit" not in r.stderr           # before: "a landmark recording ... (posed fit FIT.jsonl ...)"
