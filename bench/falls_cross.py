"""The cross-source check of the fall detector (issue 33 item 3): the same rules and thresholds measured on every
source, each row saying whether values were chosen on it, looked at while building, or never used, and the gap
to the source they were chosen on.

Sources: the synthetic scenarios (``tune``: the thresholds were checked on these; ``heldout``), the CMU clips,
urfd_dev (real UR Fall clips, MediaPipe Holistic landmarks), the same scenarios and CMU clips seen by a wall
camera 2 m up, 35 deg down, 320x240 with the default config (``--mount wall``: the private recordings' setting)
and by a second one in a room's corner that no rule was built on (``--mount corner``: 2.4 m, 25 deg, 74 deg),
the three cameras again with world landmarks (``--world``) and with the 2D landmarks as MediaPipe Holistic
gives them (``--extractor holistic``: the private recordings' extractor), and real videos of the shared data
run through posed's own landmark stage (``posed landmarks``; daily activities only) with the default config. A
gap is the source's recall (false-alarm rate) minus that of the source the values were chosen on.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from posed.bench.landmark_cache import stage_tag

# real videos of the shared data, all daily activities: (path under shared/data, what happens, role)
VIDEOS = (
    ("reference/tfjs_pose_squats/pose_squats.mp4", "squats, front view", "held out"),
    ("reference/multi_person/bend_hand.mp4", "bending deeply over a planter, handheld camera", "held out"),
    ("reference/multi_person/store_aisle.gif", "shoppers, high camera behind them", "held out"),
    ("reference/multi_person/s2d_enter.mp4", "a man jumps off a block behind it",
     "looked at (the another-level rule)"),
    ("reference/pose2sim_demo/balancing/cam01.mp4", "balancing on one leg, 60 fps portrait", "held out"),
    ("reference/pose2sim_demo/balancing/cam02.mp4", "the same, second view", "held out"),
)


@dataclass(frozen=True)
class Row:
    source: str
    role: str          # chosen on | held out | looked at (what)
    geometry: str
    falls: int
    detected: int
    adl: int
    false_alarms: int
    median_latency_s: float | None

    @property
    def recall(self) -> float | None:
        return self.detected / self.falls if self.falls else None

    @property
    def fa_rate(self) -> float | None:
        return self.false_alarms / self.adl if self.adl else None

    def to_json(self, ref: Row | None = None) -> dict:
        out = {"source": self.source, "role": self.role, "geometry": self.geometry, "falls": self.falls,
               "detected": self.detected, "recall": self.recall, "adl": self.adl,
               "false_alarms": self.false_alarms, "false_alarm_rate": self.fa_rate,
               "median_latency_s": self.median_latency_s}
        if ref is not None:
            out["recall_gap"] = None if self.recall is None or ref.recall is None else round(self.recall - ref.recall, 3)
            out["false_alarm_rate_gap"] = None if self.fa_rate is None or ref.fa_rate is None else \
                round(self.fa_rate - ref.fa_rate, 3)
        return out


def _synthetic_row(source, role, geometry_text, report) -> Row:
    falls = report["falls"]
    return Row(source, role, geometry_text, falls, round((report["recall"] or 0) * falls), report["adl"],
               report["false_alarms"], report["median_latency_s"])


def _recordings_row(source, role, geometry_text, r) -> Row:
    return Row(source, role, geometry_text, r["falls"], r["detected"], r["adl"], r["false_alarms"],
               r["median_latency_s"])


def video_recordings(shared: Path, out_dir: Path, log: Callable[[str], None] = lambda s: None) -> Path:
    """A folder in ``out_dir``, one per version of the landmark stage (bench.landmark_cache), with one ``posed
    landmarks`` recording per video of ``VIDEOS`` (made once, then reused) and a labels.json marking each a
    daily activity, with no camera geometry (the default config judges them)."""
    out_dir = out_dir / f"landmarks-{stage_tag()}"
    out_dir.mkdir(parents=True, exist_ok=True)
    clips = []
    for rel, what, _role in VIDEOS:
        video = shared / rel
        if not video.is_file():
            raise FileNotFoundError(f"{video} is missing: the videos live in shared/data/reference "
                                    "(set POSED_SHARED_DATA or run from the project root)")
        name = Path(rel).stem if "balancing" not in rel else f"balancing_{Path(rel).stem}"
        rec = out_dir / f"{name}.landmarks.jsonl"
        if not rec.is_file():
            log(f"landmarks: {rel} (posed landmarks, once)")
            subprocess.run([sys.executable, "-m", "posed.cli", "landmarks", str(video), "-o", str(rec)],
                           check=True, capture_output=True)
        clips.append({"clip": name, "label": "adl", "impact_t": None, "what": what})
    (out_dir / "labels.json").write_text(json.dumps({"dataset": "shared/data real videos through posed landmarks",
                                                     "camera": {}, "clips": clips}, indent=1))
    return out_dir


def run_cross(shared: Path, cfg, recordings: Path, cache: Path | None, videos_dir: Path,
              log: Callable[[str], None] = lambda s: None) -> dict:
    """Every source's row (``cfg``: the daemon config, whose ``falls`` section is the detector's)."""
    from posed.bench.falls import run_bench
    from posed.bench.falls_recordings import run_recordings

    falls = cfg.falls
    rows: list[Row] = []

    def synth(splits, geometry, mount, source, role, text, fitting=cfg.fitting, world=False, extractor="blazepose"):
        log(f"{source} ...")
        rep = run_bench(splits, "real", falls, "", shared, None, fitting, True, cache, geometry, mount, world,
                        extractor)
        rows.append(_synthetic_row(source, role, text, rep))
        return rep

    synth(("tune",), "given", "robot", "synthetic tune, robot camera", "chosen on", "given")
    synth(("heldout",), "given", "robot", "synthetic heldout, robot camera", "held out", "given")
    synth(("cmu",), "given", "robot", "CMU 131_01/02, robot camera", "held out", "given")
    synth(("tune", "heldout", "cmu"), "default", "robot", "synthetic + CMU, robot camera",
          "looked at (the floor rules, issue 33)", "default config")
    synth(("tune", "heldout", "cmu"), "default", "wall", "synthetic + CMU, wall camera 2 m 35 deg 320x240",
          "looked at (the body check, issue 33)", "default config, no intrinsics (assumed lens)")
    synth(("tune", "heldout", "cmu"), "default", "wall", "the same, fitted orthographically (the paper's camera)",
          "looked at (the body check and the floor rules, issue 33)", "default config, fitting.projection orthographic",
          replace(cfg.fitting, projection="orthographic"))
    synth(("tune", "heldout", "cmu"), "default", "corner", "synthetic + CMU, corner camera 2.4 m 25 deg 320x240 74 deg",
          "held out (added 2026-12-05 after every rule; one CMU clip traced for the walking feet)", "default config, no intrinsics (assumed lens)")
    # the same three cameras with the evidence the daemon's fit has: BlazePose world landmarks (bench.falls_world)
    world = "default config, with world landmarks (the daemon's evidence)"
    synth(("tune", "heldout", "cmu"), "default", "robot", "synthetic + CMU, robot camera, world landmarks",
          "looked at (the floor rules, issue 33)", world, world=True)
    synth(("tune", "heldout", "cmu"), "default", "wall", "synthetic + CMU, wall camera, world landmarks",
          "looked at (the body check, issue 33)", world + ", no intrinsics (assumed lens)", world=True)
    synth(("tune", "heldout", "cmu"), "default", "corner", "synthetic + CMU, corner camera, world landmarks",
          "held out", world + ", no intrinsics (assumed lens)", world=True)
    # the same three cameras with the 2D landmarks MediaPipe Holistic gives (the private recordings' extractor:
    # no elbows, few wrists, 3 of 8 falls lost on the floor after the impact; bench.falls_extractor)
    holistic = "default config, landmarks as MediaPipe Holistic gives them"
    synth(("tune", "heldout", "cmu"), "default", "robot", "synthetic + CMU, robot camera, Holistic's landmarks",
          "held out", holistic, extractor="holistic")
    synth(("tune", "heldout", "cmu"), "default", "wall", "synthetic + CMU, wall camera, Holistic's landmarks",
          "looked at (lost_while_lying: traced scenes, issue 33)", holistic + ", no intrinsics (assumed lens)",
          extractor="holistic")
    synth(("tune", "heldout", "cmu"), "default", "corner", "synthetic + CMU, corner camera, Holistic's landmarks",
          "held out", holistic + ", no intrinsics (assumed lens)", extractor="holistic")
    log("urfd_dev ...")
    looked = "looked at (lost_confirm_s, lost_descent_confirm_s, the body check's 20 deg, lost_while_lying's box)"
    r = run_recordings(recordings, cfg, "labels", cache)
    rows.append(_recordings_row("urfd_dev (real, MediaPipe Holistic)", looked, "labelled", r))
    r = run_recordings(recordings, cfg, "config", cache)
    rows.append(_recordings_row("urfd_dev (real, MediaPipe Holistic)", looked, "default config", r))
    folder = video_recordings(shared, videos_dir, log)
    r = run_recordings(folder, replace(cfg, falls=falls), "config", cache)
    rows.append(_recordings_row("real videos, posed's landmark stage", "held out (s2d_enter looked at)",
                                "default config", r))
    clips = {c["name"]: c for c in r["clips"]}
    ref = rows[0]
    return {"rows": [row.to_json(ref) for row in rows], "reference": ref.source,
            "videos": [{"video": rel, "what": what, "role": role,
                        "states": clips[(Path(rel).stem if "balancing" not in rel
                                         else f"balancing_{Path(rel).stem}")]["states"]}
                       for rel, what, role in VIDEOS]}


def table(report: dict) -> str:
    """The rows as a Markdown table."""
    lines = ["| source | values | geometry | recall | gap | false alarms | gap (rate) | median latency (s) |",
             "|---|---|---|---|---|---|---|---|"]

    def pct(v):
        return "n/a" if v is None else f"{100 * v:.1f} %"

    for r in report["rows"]:
        rec = "n/a" if not r["falls"] else f"{r['detected']}/{r['falls']} ({pct(r['recall'])})"
        gap = "" if r.get("recall_gap") is None else f"{100 * r['recall_gap']:+.1f}"
        fgap = "" if r.get("false_alarm_rate_gap") is None else f"{100 * r['false_alarm_rate_gap']:+.1f}"
        lines.append(f"| {r['source']} | {r['role']} | {r['geometry']} | {rec} | {gap} | "
                     f"{r['false_alarms']}/{r['adl']} | {fgap} | {r['median_latency_s']} |")
    return "\n".join(lines) + "\n"
