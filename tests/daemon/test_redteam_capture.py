"""Bad frames in a ``file:`` image folder, through the real ``posed run`` (real model, real fit, real Zenoh on
127.0.0.1): a 10000x10000 image (above the 8K that posed decodes at all) and an image that does not decode are
skipped and counted, never fatal, each with the fix that fits it."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from posed.hal import MAX_DECODE_PIXELS
from tests.daemon.zenoh_util import client, free_port

ROOT = Path(__file__).resolve().parents[2]


def test_oversized_and_corrupt_images_are_skipped_and_counted(tmp_path, squat_frames):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(0, 12, 3):
        cv2.imwrite(str(folder / f"img_{i:02d}.png"), squat_frames[i])
    cv2.imwrite(str(folder / "img_04.png"), np.zeros((10000, 10000, 3), np.uint8))    # 1e8 pixels
    (folder / "img_07.png").write_bytes(b"\x89PNG\r\n\x1a\n not really a png")
    ep = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "out.log"
    with open(out, "w") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "run", "--source", f"file:{folder}",
                                 "--set", f"pipeline.state_dir={tmp_path / 'state'}", "--set", "logging.format=json",
                                 "--set", f"zenoh.listen=[{ep}]", "--set", "robot_id=rt",
                                 "--set", "pipeline.status_period_s=0.3", "--set", "source.realtime=false",
                                 "--set", "pipeline.stop_at_end=true", "--set", "source.fps=5"],
                                cwd=ROOT, stdout=fh, stderr=subprocess.STDOUT)
    statuses = []
    try:
        with client(ep) as s:
            _sub = s.declare_subscriber("posed/rt/status", lambda smp: statuses.append(
                json.loads(smp.payload.to_string())))
            proc.wait(180)
    finally:
        if proc.poll() is None:
            proc.kill()
    log = out.read_text()
    assert proc.returncode == 0, log[-3000:]
    lines = [json.loads(x) for x in log.splitlines() if x.startswith("{")]
    skipped = [x for x in lines if x.get("event") == "frame_skipped"]
    assert {Path(x["file"]).name for x in skipped if x.get("file")} >= {"img_04.png", "img_07.png"} or \
        len(skipped) >= 2, skipped
    assert not [x for x in lines if x.get("event") in ("stage_failed", "stage_exited", "stage_dead")]
    cap = [st["stages"]["capture"] for st in statuses if "capture" in st.get("stages", {})]
    assert cap and max(c["restarts"] for c in cap) == 0
    assert max(c["bad_frames"] for c in cap) == 2, cap[-1]
    assert max(c["frames"] for c in cap) == 4, cap[-3:]
    too_large = next(x for x in skipped if "img_04" in x.get("error", ""))
    text = too_large["error"] + " " + too_large.get("fix", "")
    # not "raise pipeline.frame_max_pixels" (frames up to 8K are scaled down at capture, never skipped for their
    # size): the image is above what posed decodes at all, and the fix says to scale it below that
    assert "frame_max_pixels to" not in text, text
    assert f"scale the image down to at most {MAX_DECODE_PIXELS} pixels" in too_large["fix"], text
    assert "replace or delete" not in too_large["fix"], text
    corrupt = next(x for x in skipped if "img_07" in x.get("error", ""))
    assert "replace or delete the image" in corrupt["fix"], corrupt


def test_ring_message_for_a_frame_written_unscaled(tmp_path):
    from posed.daemon.proc.ring import FrameRing, FrameTooLarge

    ring = FrameRing.create(2, 640 * 480, False)
    try:
        try:
            ring.write(np.zeros((720, 1280, 3), np.uint8), 0, time.monotonic())
        except FrameTooLarge as exc:
            assert "(pipeline.frame_max_pixels): scale it down first by hal.scale_factor" in str(exc)
        else:
            raise AssertionError("a 1280x720 frame fitted a 640x480 slot")
    finally:
        ring.close()
