"""Real fall recordings with a real bystander (issue 36): two labelled landmark recordings placed side by side.

Each clip of a labelled folder (``shared/data/falls/urfd_dev``: real people, MediaPipe landmarks of real video)
is joined by another person: the next daily-activity clip of the same folder (in turn, never the clip itself),
whose landmarks are turned ``PAN_DEG`` to the right about the camera's vertical axis (exactly what the same
camera would see of them standing there: :func:`panned`; the clips' camera is level, so gravity is unchanged).
The recording becomes one twice as wide (1280x480 for the 640x480 clips) with the same intrinsics, so the
clip's own person keeps exactly the pixels, rays and fit they had alone; the bystander is seen in the right
half. When the bystander's clip
ends, they are gone (held in their last pose instead, a clip ending lying on a bed became a person lying still
for longer than the clip showed: an alarm the clip alone never had the time to raise).

The frames are those ``posed run`` would take (``pipeline.target_fps``); each frame carries ``people`` with
track ids from :class:`landmarks.tracks.PersonTracker` with the daemon's landmark slots
(:mod:`bench.people_tracks`) and its own ``landmarks`` are the person followed
longest's, as :class:`landmarks.people.MultiPoseLandmarker` writes them. The recording then goes through what
``posed falls`` runs (a fitter and a fall detector per person, :mod:`posed.commands.falls`), and once more with
the clip's person alone on the same wide canvas.

Counted: falls whose person got a ``falling``/``on_floor`` message (recall), daily activities whose person got
one (false alarms), messages for the bystander (their own daily activity judged: compare with the same clips'
false alarms alone), falls with more than one event id for their person, and the same alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from posed.bench.falls import DETECTING_STATES as DETECTING
from posed.bench.falls_recordings import read_labels, with_geometry
from posed.bench.people_tracks import NamedBodies
from posed.camera_model import Intrinsics
from posed.daemon.config import Config
from posed.landmarks import LandmarkFrame, PersonLandmarks, RecordingHeader, read_recording

PAN_DEG = 45.0     # the bystander stands this far to the right of the camera's axis (about the vertical)


def panned(landmarks: np.ndarray, cam: Intrinsics, deg: float) -> np.ndarray:
    """``landmarks`` (pixels of ``cam``) as the same camera sees them after the person moved ``deg`` to the
    right around the camera's vertical axis (the image of a camera panned left by ``deg``: the homography
    K R K^-1; a level camera's gravity is unchanged by it). Visibility, presence and z are kept."""
    out = np.array(landmarks, float, copy=True)
    a = np.radians(deg)
    x = (out[:, 0] - cam.cx) / cam.fx
    y = (out[:, 1] - cam.cy) / cam.fy
    xr, zr = x * np.cos(a) + np.sin(a), -x * np.sin(a) + np.cos(a)
    out[:, 0] = cam.cx + cam.fx * xr / zr
    out[:, 1] = cam.cy + cam.fy * y / zr
    return out


def compose(own: tuple, other: tuple, pipeline_config, alone: bool = False) -> tuple[RecordingHeader, list, dict]:
    """(header, frames, who) of ``own`` (header, frames) with ``other``'s person beside them (module doc);
    ``who`` maps each track id to "own" or "bystander"."""
    from posed.commands.falls import taken_frames

    h_own, f_own = own
    f_other = other[1]
    width, height = h_own.image_size
    cam = h_own.camera
    wide = Intrinsics(cam.fx, cam.fy, cam.cx, cam.cy, 2 * width, height) if cam is not None else None
    header = RecordingHeader((2 * width, height), h_own.fps, f"{h_own.source} + a bystander beside", wide)
    mine = list(taken_frames(pipeline_config, f_own))
    theirs = list(taken_frames(pipeline_config, f_other))
    bodies = NamedBodies()
    who: dict[int, str] = {}
    out = []
    for k, fr in enumerate(mine):
        seen = []
        if fr.landmarks is not None:
            seen.append(("own", fr.landmarks))
        if not alone and k < len(theirs) and theirs[k].landmarks is not None:
            seen.append(("bystander", panned(theirs[k].landmarks, cam, PAN_DEG)))
        ids = bodies.update(fr.t, seen)
        for (name, _), tid in zip(seen, ids, strict=True):
            who[tid] = name
        people = tuple(PersonLandmarks(tid, lm) for (_, lm), tid in zip(seen, ids, strict=True))
        main = bodies.tracker.longest_followed(list(ids))
        landmarks = next((p.landmarks for p in people if p.id == main), None)
        out.append(LandmarkFrame(fr.seq, fr.t, landmarks, people=people))
    return header, out, who


def run(folder: Path, cfg: Config | None = None, geometry: str = "labels", only: str = "",
        progress=lambda m: None) -> dict:
    """Every clip of ``folder`` with a bystander and alone (module doc)."""
    from posed.commands.falls import detect, fit_frames, sides_kept

    cfg = with_geometry(cfg or Config(), read_labels(folder).get("camera", {}), geometry)
    labels = read_labels(folder)
    clips = labels["clips"]
    adl = [c for c in clips if c["label"] == "adl"]
    rows = []
    for i, c in enumerate(clips):
        if only and only not in c["clip"]:
            continue
        partner = next(a for a in adl[i % len(adl):] + adl if a["clip"] != c["clip"])
        own = _read(folder / f"{c['clip']}.landmarks.jsonl")
        other = _read(folder / f"{partner['clip']}.landmarks.jsonl")
        row = {"clip": c["clip"], "label": c["label"], "bystander_clip": partner["clip"]}
        for mode in ("with_bystander", "alone"):
            header, frames, who = compose(own, other, cfg.pipeline, alone=mode == "alone")
            messages = [m for _f, _r, evs in detect(cfg, header, fit_frames(
                cfg, header, sides_kept(header, frames, cfg.landmarks.keep_sides)))
                        for m in evs]
            mine = [m for m in messages if who.get(m.extra.get("person")) == "own" or
                    (m.extra.get("person") is None and mode == "alone")]
            theirs = [m for m in messages if who.get(m.extra.get("person")) == "bystander"]
            first = next((m for m in mine if m.state in DETECTING), None)
            row[mode] = {"detected": first is not None, "event_ids": len({m.id for m in mine}),
                         "bystander_events": len({m.id for m in theirs}),
                         "latency_s": None if first is None or c.get("impact_t") is None
                         else round(first.t_detect - c["impact_t"], 3),
                         "states": [f"{m.extra.get('person')}:{m.state}" for m in messages]}
        rows.append(row)
        progress(f"{c['clip']} + {partner['clip']}: {row['with_bystander']['states']} (alone "
                 f"{row['alone']['states']})")
    return {"folder": str(folder), "geometry": geometry, "clips": rows,
            "with_bystander": _summary(rows, "with_bystander"), "alone": _summary(rows, "alone")}


def _read(path: Path) -> tuple:
    header, frames, _problems = read_recording(path)
    return header, frames


def _summary(rows: list[dict], mode: str) -> dict:
    falls = [r[mode] for r in rows if r["label"] == "fall"]
    adl = [r[mode] for r in rows if r["label"] != "fall"]
    return {"falls": len(falls), "detected": sum(r["detected"] for r in falls), "adl": len(adl),
            "false_alarms": sum(r["detected"] for r in adl),
            "bystander_events": sum(r["bystander_events"] for r in falls + adl),
            "second_events": sum(r["event_ids"] > 1 for r in falls)}
