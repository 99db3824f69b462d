"""Fall detection on labelled real recordings: a folder of ``*.landmarks.jsonl`` and its ``labels.json``.

``labels.json`` (as in shared/data/falls/urfd_dev): ``clips`` — each ``{"clip": NAME, "label": "fall"|"adl",
"impact_t": seconds from the clip start or null}`` for ``NAME.landmarks.jsonl`` — and ``camera`` — the
recordings' geometry (``camera_tilt_deg``, ``camera_roll_deg``, ``camera_height_m``; the intrinsics are in
each recording's header).

Every clip goes through exactly what ``posed falls`` runs (posed.commands.falls: the frames the capture
stage takes at ``pipeline.target_fps``, the fitting stage's StreamFit in video mode, the publisher stage's
FallWatch). A fall counts as detected by its first
``falling`` or ``on_floor`` message; latency = that message's ``t_detect`` minus ``impact_t``; a daily
activity with any such message is a false alarm. The fits are cached (``~/.cache/posed/falls-fits``) under a
key of the recording's bytes, the fit config and the fitting package's source, so re-scoring with other
detector settings costs no fit.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import statistics
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from posed.daemon.config import Config

DETECTING_STATES = ("falling", "on_floor")
GEOMETRY_KEYS = ("camera_tilt_deg", "camera_roll_deg", "camera_height_m")


@dataclass
class RecordingOutcome:
    name: str
    kind: str
    impact_t: float | None
    detected: bool
    latency_s: float | None
    states: list[str] = field(default_factory=list)
    features: list[str] = field(default_factory=list)
    confidence: float | None = None
    frames: int = 0
    fit_ok: int = 0
    person_frames: int = 0

    def to_json(self) -> dict:
        out = asdict(self)
        out["latency_s"] = None if self.latency_s is None else round(self.latency_s, 3)
        return out


def read_labels(folder: Path) -> dict:
    path = folder / "labels.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing: a recordings folder needs labels.json "
                                "({\"clips\": [{\"clip\", \"label\": fall|adl, \"impact_t\"}], \"camera\": {...}})")
    labels = json.loads(path.read_text())
    for c in labels.get("clips", []):
        if c.get("label") not in ("fall", "adl"):
            raise ValueError(f"{path}: clip {c.get('clip')!r} has label {c.get('label')!r}; valid: fall, adl")
        if not (folder / f"{c['clip']}.landmarks.jsonl").is_file():
            raise FileNotFoundError(f"{folder / (c['clip'] + '.landmarks.jsonl')} is listed in labels.json but missing")
    return labels


def with_geometry(cfg: Config, camera: dict, geometry: str) -> Config:
    """``geometry``: "labels" sets the labelled tilt, roll and height; "config" keeps the config's (e.g. auto)."""
    if geometry != "labels":
        return cfg
    falls = replace(cfg.falls, camera_geometry="measured", **{k: camera[k] for k in GEOMETRY_KEYS if k in camera})
    return replace(cfg, falls=falls)


def _fitting_source_hash() -> str:
    from posed import fitting

    h = hashlib.sha256()
    for p in sorted(Path(fitting.__file__).parent.glob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cached_fits(path: Path, cfg: Config, cache: Path | None):
    """(header, [(frame, FitResult)]) of one recording, fitted as ``posed falls`` fits it (cached)."""
    from posed.commands.falls import fit_frames, sides_kept, taken_frames
    from posed.fitting import FitResult
    from posed.landmarks import RecordingSides, read_recording

    header, frames, _problems = read_recording(path)
    # what the daemon's capture stage takes from a recording, and sends on with left and right kept
    frames = list(sides_kept(header, taken_frames(cfg.pipeline, frames), cfg.landmarks.keep_sides))
    key = None
    if cache is not None:
        h = hashlib.sha256(path.read_bytes())
        h.update(json.dumps(asdict(cfg.fitting), sort_keys=True).encode())
        h.update(f"target_fps={cfg.pipeline.target_fps} keep_sides={cfg.landmarks.keep_sides} "
                 f"lens={header.camera or cfg.falls.camera_hfov_deg}".encode())
        h.update(_fitting_source_hash().encode())
        h.update(Path(inspect.getfile(RecordingSides)).read_bytes())   # what put back the labels the fit had
        key = cache / f"{path.name}.{h.hexdigest()[:20]}.fits.jsonl"
        if key.is_file():
            results = [FitResult.from_json(json.loads(line)) for line in key.read_text().splitlines()]
            if len(results) == len(frames):
                return header, list(zip(frames, results, strict=True))
    pairs = [(frame, result) for frame, result, _others in fit_frames(cfg, header, frames)]
    if key is not None:
        from posed.daemon.bus.payloads import dumps

        key.parent.mkdir(parents=True, exist_ok=True)
        tmp = key.with_suffix(".tmp")
        tmp.write_text("".join(dumps(r.to_json()) + "\n" for _, r in pairs))
        tmp.replace(key)
    return header, pairs


def score_clip(name: str, kind: str, impact_t: float | None, header, pairs, cfg: Config) -> RecordingOutcome:
    from posed.commands.falls import detect

    messages = []
    for _frame, _result, evs in detect(cfg, header, pairs):
        messages += evs
    first = next((m for m in messages if m.state in DETECTING_STATES), None)
    latency = None
    if first is not None and kind == "fall" and impact_t is not None:
        latency = first.t_detect - impact_t
    return RecordingOutcome(name, kind, impact_t, first is not None, latency, [m.state for m in messages],
                            list(first.features) if first else [], first.confidence if first else None,
                            len(pairs), sum(r.ok for _, r in pairs),
                            sum(f.landmarks is not None for f, _ in pairs))


def summarise(outcomes: list[RecordingOutcome]) -> dict:
    falls = [o for o in outcomes if o.kind == "fall"]
    adl = [o for o in outcomes if o.kind == "adl"]
    lat = [o.latency_s for o in falls if o.detected and o.latency_s is not None]
    return {"falls": len(falls), "adl": len(adl), "detected": sum(o.detected for o in falls),
            "recall": sum(o.detected for o in falls) / len(falls) if falls else None,
            "false_alarms": sum(o.detected for o in adl),
            "median_latency_s": round(statistics.median(lat), 3) if lat else None,
            "max_latency_s": round(max(lat), 3) if lat else None}


def run_recordings(folder: Path, cfg: Config, geometry: str = "labels", cache: Path | None = None,
                   only: str = "", progress: Callable[[RecordingOutcome], None] | None = None) -> dict:
    labels = read_labels(folder)
    cfg = with_geometry(cfg, labels.get("camera", {}), geometry)
    outcomes = []
    for c in labels["clips"]:
        if only and only not in c["clip"]:
            continue
        header, pairs = cached_fits(folder / f"{c['clip']}.landmarks.jsonl", cfg, cache)
        o = score_clip(c["clip"], c["label"], c.get("impact_t"), header, pairs, cfg)
        outcomes.append(o)
        if progress:
            progress(o)
    return {"folder": str(folder), "geometry": geometry,
            "falls_config": {k: getattr(cfg.falls, k) for k in GEOMETRY_KEYS},
            "clips": [o.to_json() for o in outcomes], **summarise(outcomes)}
