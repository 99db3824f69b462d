"""The inputs of the chaos campaign (``posed bench chaos``), made from real data with a corrupt frame every N:

* ``squat``: the real squat video (tfjs_pose_squats) as a folder of JPEG images, every N-th replaced by bytes
  that do not decode, and (``crafted``) every N-th of the rest by a crafted JPEG: a header that claims
  24000 x 24000 pixels with stray bytes after its APP0 segment and no image data (issue 34 item 4: never
  decoded; the capture stage must skip and count both, hal.images);
* ``falls``: real UR Fall Detection recordings (urfd_dev, camera 0) joined into one landmark recording, falls
  alternating with daily activities so that each pass has several falls and the person stands up between
  them; every N-th frame line is replaced by text that is not a frame (the reader reports and skips it); with
  ``clock_jumps`` the recording's clock leaps +1e9 s, repeats one timestamp for ten frames and goes back
  1,000 s at three clip boundaries (issue 34 item 6: the replay's capture clock must carry on, hal.ReplayClock).

Both are replayed in a loop at their own frame rate (``source.loop``, ``source.realtime``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

SQUAT_VIDEO = Path("reference") / "tfjs_pose_squats" / "pose_squats.mp4"
URFD = Path("falls") / "urfd_dev"
# falls whose person stays in view after the impact (labels.json person_after_impact_s >= 1 s), each followed
# by a daily activity with a standing person
FALL_SEQUENCE = ("urfd_02_fall", "urfd_16_adl", "urfd_04_fall", "urfd_22_adl", "urfd_10_fall", "urfd_38_adl",
                 "urfd_14_fall", "urfd_40_adl")
CORRUPT_BYTES = b"\xff\xd8\xff\xe0 posed chaos: this is not a JPEG \x00\x01\x02"
CORRUPT_LINE = '{"seq": "posed chaos: this is not a frame", "landmarks": [[1, 2]'
CLOCK_LEAP_S = 1e9          # a clock set from nothing to NTP time
CLOCK_BACK_S = 1000.0       # a clock stepped back
CLOCK_REPEATS = 10          # frames stamped with one timestamp (a stuck clock)


def crafted_jpeg(width: int = 24000, height: int = 24000) -> bytes:
    """A JPEG header that claims ``width`` x ``height`` pixels, three stray bytes after its APP0 segment and no
    scan data: decoding it would allocate width x height x 3 bytes (1.7 GB at 24000 x 24000)."""
    app0 = b"\xff\xe0" + (16).to_bytes(2, "big") + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
    sof0 = (b"\xff\xc0" + (17).to_bytes(2, "big") + b"\x08" + height.to_bytes(2, "big") + width.to_bytes(2, "big")
            + b"\x03" + b"\x01\x22\x00" + b"\x02\x11\x01" + b"\x03\x11\x01")
    return b"\xff\xd8" + app0 + b"\x00\x00\x00" + sof0 + b"\xff\xd9"


@dataclass(frozen=True)
class ChaosInput:
    """One prepared input: the ``--source`` URI, the config overrides it needs, and what it holds."""

    name: str
    source: str
    overrides: tuple[str, ...]
    frames: int             # frames per pass, corrupt ones included
    corrupt: int            # corrupt frames per pass (crafted images included)
    falls_per_pass: int
    pass_s: float           # seconds of one pass at the recording's frame rate


def squat_images(shared: Path, out: Path, corrupt_every: int, crafted: bool = False) -> ChaosInput:
    """The squat video's frames as JPEG files ``frame_<i>.jpg``; every ``corrupt_every``-th is garbage and, with
    ``crafted``, the one after it a crafted oversized header (:func:`crafted_jpeg`)."""
    import cv2

    video = shared / SQUAT_VIDEO
    if not video.is_file():
        raise FileNotFoundError(f"{video}: the real squat video is missing (POSED_SHARED_DATA)")
    out.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(video))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    n = corrupt = 0
    try:
        while True:
            ok, image = cap.read()
            if not ok:
                break
            path = out / f"frame_{n}.jpg"
            if corrupt_every and n % corrupt_every == corrupt_every - 1:
                path.write_bytes(CORRUPT_BYTES)
                corrupt += 1
            elif crafted and corrupt_every and n % corrupt_every == 0 and n:
                path.write_bytes(crafted_jpeg())
                corrupt += 1
            else:
                cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 90])
            n += 1
    finally:
        cap.release()
    return ChaosInput("squat", f"file:{out}", (f"source.fps={fps:g}",), n, corrupt, 0, n / fps)


def fall_recording(shared: Path, out: Path, corrupt_every: int, clock_jumps: bool = False) -> ChaosInput:
    """The clips of FALL_SEQUENCE joined into one recording (seq and t renumbered, 30 fps), every
    ``corrupt_every``-th frame line replaced by CORRUPT_LINE; the falls settings from labels.json. With
    ``clock_jumps``: the clock leaps CLOCK_LEAP_S ahead before the 2nd clip, stands still for CLOCK_REPEATS
    frames at the start of the 4th and steps CLOCK_BACK_S back before the 6th (each clip a daily activity
    or a fall whose person stands up again)."""
    folder = shared / URFD
    labels = json.loads((folder / "labels.json").read_text())
    cam = labels["camera"]
    header = None
    lines: list[str] = []
    offset = 0.0            # what the clock jumps added so far, seconds
    for k, clip in enumerate(FALL_SEQUENCE):
        rows = (folder / f"{clip}.landmarks.jsonl").read_text().splitlines()
        header = header or json.loads(rows[0])
        if clock_jumps and k == 1:
            offset += CLOCK_LEAP_S
        if clock_jumps and k == 5:
            offset -= CLOCK_BACK_S
        first = len(lines)
        for row in rows[1:]:
            if not row.strip():
                continue
            frame = json.loads(row)
            frame["seq"] = len(lines)
            n = first if clock_jumps and k == 3 and len(lines) - first < CLOCK_REPEATS else len(lines)
            frame["t"] = round(offset + n / float(header["fps"]), 4)
            lines.append(json.dumps(frame))
    corrupt = 0
    for i in range(len(lines)):
        if corrupt_every and i % corrupt_every == corrupt_every - 1:
            lines[i] = CORRUPT_LINE
            corrupt += 1
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(header) + "\n" + "\n".join(lines) + "\n")
    overrides = (f"falls.camera_height_m={cam['camera_height_m']}", f"falls.camera_tilt_deg={cam['camera_tilt_deg']}",
                 f"falls.camera_roll_deg={cam['camera_roll_deg']}", "pipeline.target_fps=30")
    falls = sum(1 for c in FALL_SEQUENCE if c.endswith("_fall"))
    return ChaosInput("falls", f"file:{out}", overrides, len(lines), corrupt, falls,
                      len(lines) / float(header["fps"]))
