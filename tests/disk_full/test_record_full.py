"""``posed record`` on a disk that fills up: it stops before the first frame the disk cannot take, the video
plays and holds exactly the frames its sidecar lists, and it exits 73 naming the folder."""

from __future__ import annotations

import json
import os

import cv2

from posed import hal
from posed.hal.sidecar import read_sidecar
from tests.disk_full.conftest import SQUAT_VIDEO, posed

SOURCE = f"file:{SQUAT_VIDEO}?realtime=false"


def _frames_in(video) -> int:
    cap = cv2.VideoCapture(str(video))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def test_record_on_a_full_disk_stops_and_exits_73_naming_the_folder(tmpfs):
    mnt = tmpfs("1m")
    out = mnt / "r.avi"
    r = posed("record", "--source", SOURCE, "-o", str(out))
    # before: rc 0, {"frames": 65, "problems": {}}, the file held 21 frames and the sidecar listed 65
    assert r.returncode == 73, (r.stdout, r.stderr)
    summary = json.loads(r.stdout.strip().splitlines()[-1])
    n = summary["frames"]
    assert summary["reason"] == "disk full" and 0 < n < 65
    assert f"disk full at {mnt} after {n} frames: free space or record elsewhere" in r.stderr
    assert "Traceback" not in r.stderr
    assert _frames_in(out) == n                                      # the video plays, every frame of it
    assert sorted(read_sidecar(mnt / "r.timestamps.jsonl").by_frame) == list(range(n))


def test_frames_the_writer_lost_silently_are_found_at_close_and_cut_from_the_sidecar(tmpfs, monkeypatch):
    """With the free-space check blinded, OpenCV's writer loses frames without a word: the count of the
    finished file catches it, and the sidecar is cut to the frames the file holds."""
    monkeypatch.setattr("posed.hal.recorder.free_bytes", lambda folder: None)
    mnt = tmpfs("1m")
    out = mnt / "r.avi"
    with hal.open_source(SOURCE) as src:
        summary = hal.record(src, str(out))
    assert summary.reason == "disk full" and summary.frames < 65
    assert any(f"disk full at {mnt}" in note for note in summary.notes)
    assert _frames_in(out) == summary.frames
    assert sorted(read_sidecar(mnt / "r.timestamps.jsonl").by_frame) == list(range(summary.frames))


def test_record_into_a_folder_that_does_not_exist_creates_it(tmp_path):
    out = tmp_path / "new" / "r.avi"
    r = posed("record", "--source", SOURCE, "-o", str(out), "--frames", "3")
    # before: "OpenCV cannot write MJPG video here; try another suffix", exit 64
    assert r.returncode == 0, r.stderr
    assert _frames_in(out) == 3 and os.path.isfile(tmp_path / "new" / "r.timestamps.jsonl")
