"""``posed bench people`` (issue 36): the several-people landmarker on two-person scenes composited from real
footage (bench.people_scenes), against each person alone.

Per scenario the scene is run three times through a fresh :class:`landmarks.people.MultiPoseLandmarker`
(``max_people`` 3, the default): with both people, with A alone and with B alone. In the two-person run each
frame's people are matched to A and B by their landmark overlap (:func:`landmarks.tracks.oks`) with the
one-person runs of the same frame. Reported per scenario:

* **identity switches**: for each of A and B, how often the track id given to them changes from one frame
  where they were found to the next (target: 0 while apart or crossing without touching, at most one per
  crossing with occlusion);
* **found**: the share of frames where each was found (alone, and with the other in view);
* **landmark error**: A's median distance (pixels, canvas) to her published BlazePose full landmarks
  (tfjs-models), alone and with B in view, and the ratio (target: at most 1.2); B's median distance over his 12
  body joints to his joints triangulated from pose2sim's four calibrated views and projected into B's camera
  (another model's keypoints: a floor of a few pixels either way), alone and with A, on the frames where both
  runs found him, and the ratio; and his median distance to his own one-person run;
* **speed**: milliseconds per frame of the two-person and the one-person runs, landmark passes per frame.

Pixels are the 1280x720 canvas's; times wall-clock on this machine, one thread per onnxruntime session as
the daemon runs it.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

from posed.bench import people_scenes as scenes
from posed.bench.mocap_landmarks import BODY12_IDX
from posed.bench.people_tracks import switches

MATCH_MIN = 0.3          # landmark overlap with a person's own one-person run to count as them


def _run(frames: list[np.ndarray], models_dir: Path | None) -> tuple[list, float, float]:
    """MultiPoseLandmarker results per frame, ms per frame (median) and landmark passes per frame (mean)."""
    from posed.landmarks import LandmarkConfig, MultiPoseLandmarker

    lm = MultiPoseLandmarker(LandmarkConfig(max_people=3), models_dir)
    lm.warmup()
    out, times, passes = [], [], []
    for k, image in enumerate(frames):
        t0 = time.perf_counter()
        r = lm.process_full(image, k / 5.0, k)
        times.append((time.perf_counter() - t0) * 1000.0)
        passes.append(r.timings_ms.get("landmark_passes", len(r.people) or (r.frame.landmarks is not None)))
        out.append(r)
    return out, statistics.median(times), float(np.mean(passes))


def _persons(result) -> list[tuple[int, np.ndarray]]:
    """(track id, (33, 5) landmarks) of everyone in a frame; one person without ``people``: the frame's own."""
    if result.frame.people:
        return [(p.id, np.asarray(p.landmarks)) for p in result.frame.people]
    if result.frame.landmarks is not None:
        return [(result.primary if result.primary is not None else 0, np.asarray(result.frame.landmarks))]
    return []


def _size(lms: np.ndarray) -> float:
    from posed.landmarks import landmark_box

    x0, y0, x1, y1 = landmark_box(lms)
    return max(float(np.sqrt(max(x1 - x0, 0.0) * max(y1 - y0, 0.0))), 1.0)


def _median_px(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a[:, :2] - b[:, :2], axis=1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else float("nan")


def _ratio(alone: list[float], both: list[float]) -> dict:
    """Mean error alone and with the other person (the same frames), and their ratio."""
    if not alone:
        return {"alone": None, "with_a": None, "ratio": None, "frames": 0}
    m_alone, m_both = float(np.nanmean(alone)), float(np.nanmean(both))
    return {"alone": round(m_alone, 1), "with_a": round(m_both, 1),
            "ratio": round(m_both / m_alone, 3) if m_alone > 0 else None, "frames": len(alone)}


def evaluate(scenario: scenes.Scenario, a: scenes.Clip, b: scenes.Clip, models_dir: Path | None) -> dict:
    from posed.landmarks import oks

    both, maps = scenes.compose(a, b, scenario, "ab")
    only_a, _ = scenes.compose(a, b, scenario, "a")
    only_b, _ = scenes.compose(a, b, scenario, "b")
    run_ab, ms_ab, passes_ab = _run(both, models_dir)
    run_a, ms_a, _ = _run(only_a, models_dir)
    run_b, _, _ = _run(only_b, models_dir)
    ids = {"a": [], "b": []}
    err = {"a_alone": [], "a_both": [], "b_dev": [], "b_alone": [], "b_both": []}
    b_alone_at: dict[int, float] = {}
    found = {"a_alone": 0, "b_alone": 0, "a_both": 0, "b_both": 0}
    for k in range(len(both)):
        ref = {"a": _persons(run_a[k]), "b": _persons(run_b[k])}
        truth_a = scenes.truth_on_canvas(a, k, maps[k]["a"])
        if ref["a"]:
            found["a_alone"] += 1
            err["a_alone"].append(_median_px(ref["a"][0][1], truth_a))
        truth_b = scenes.truth12_on_canvas(b, k, maps[k]["b"]) if b.truth12 is not None else None
        if ref["b"]:
            found["b_alone"] += 1
            if truth_b is not None:
                b_alone_at[k] = _median_px(ref["b"][0][1][BODY12_IDX], truth_b)
        people = _persons(run_ab[k])
        taken: set[int] = set()
        for who in ("a", "b"):
            if not ref[who]:
                ids[who].append(None)
                continue
            own = ref[who][0][1]
            scores = [(oks(own, lms, _size(own)), i) for i, (_tid, lms) in enumerate(people) if i not in taken]
            best = max(scores, default=(0.0, -1))
            if best[0] < MATCH_MIN:
                ids[who].append(None)
                continue
            taken.add(best[1])
            tid, lms = people[best[1]]
            ids[who].append(tid)
            found[f"{who}_both"] += 1
            if who == "a":
                err["a_both"].append(_median_px(lms, truth_a))
            else:
                err["b_dev"].append(_median_px(lms, own))
                if k in b_alone_at:           # B's error where both runs found him, with A and alone
                    err["b_both"].append(_median_px(lms[BODY12_IDX], truth_b))
                    err["b_alone"].append(b_alone_at[k])
    a_alone = float(np.nanmean(err["a_alone"])) if err["a_alone"] else float("nan")
    a_both = float(np.nanmean(err["a_both"])) if err["a_both"] else float("nan")
    n = len(both)
    return {
        "scenario": scenario.name, "frames": n,
        "identity_switches": {"a": switches(ids["a"]), "b": switches(ids["b"])},
        "ids": {"a": sorted({i for i in ids["a"] if i is not None}), "b": sorted({i for i in ids["b"] if i is not None})},
        "found": {k: round(v / n, 3) for k, v in found.items()},
        "a_error_px": {"alone": round(a_alone, 1), "with_b": round(a_both, 1),
                       "ratio": round(a_both / a_alone, 3) if a_alone > 0 else None},
        "b_deviation_from_alone_px": round(float(np.nanmedian(err["b_dev"])), 1) if err["b_dev"] else None,
        "b_error_px": _ratio(err["b_alone"], err["b_both"]),
        "ms_per_frame": {"two_people": round(ms_ab, 1), "a_alone": round(ms_a, 1)},
        "landmark_passes_per_frame": round(passes_ab, 2),
    }


def run_bench(shared: Path, models_dir: Path | None = None, only: str = "", progress=lambda m: None,
              b_camera: str = scenes.B_CAMERA) -> dict:
    """Every scenario (or ``only``), B cut from pose2sim's ``b_camera`` (cam03, the reported view, by default;
    cam01, cam02 and cam04 are the development views a change to the landmarker is tried on first)."""
    a, b = scenes.load_clips(shared, b_camera)
    rows = []
    for sc in scenes.SCENARIOS:
        if only and only != sc.name:
            continue
        t0 = time.monotonic()
        rows.append(evaluate(sc, a, b, models_dir))
        progress(f"{sc.name}: {time.monotonic() - t0:.1f} s")
    return {"benchmark": "people", "canvas": list(scenes.CANVAS), "b_camera": b_camera, "scenarios": rows,
            "targets": {"a_error_ratio_max": 1.2, "switches_apart": 0, "switches_per_occluded_crossing_max": 1}}
