"""``posed bench people`` (issue 36): the several-people landmarker on two-person scenes composited from real
footage (bench.people_scenes), against each person alone.

Per scenario the scene is run three times through a fresh :class:`landmarks.people.MultiPoseLandmarker`
(``max_people`` 3, the default): with both people, with A alone and with B alone. In the two-person run each
frame's people are matched to A and B by their landmark overlap (:func:`landmarks.tracks.oks`) with the
one-person runs of the same frame, both at once (the pairing whose overlaps sum highest: a body is not scored
as A's because it covers the place where she stands hidden). Reported per scenario:

* **identity switches**: for each of A and B, how often the track id given to them changes from one frame
  where they were found to the next (target: 0 while apart or crossing without touching, at most one per
  crossing with occlusion);
* **found**: the share of frames where each was found (alone, and with the other in view);
* **landmark error**: A's median distance (pixels, canvas) to her published BlazePose full landmarks
  (tfjs-models), alone and with B in view, and the ratio (target: at most 1.2); B's median distance over his 12
  body joints to his joints triangulated from pose2sim's four calibrated views and projected into B's camera
  (another model's keypoints: a floor of a few pixels either way), alone and with A, on the frames where both
  runs found him, and the ratio; and his median distance to his own one-person run;
* **what the other hides**: the same ratios over only the landmarks whose truth does not fall on the other
  person's pixels drawn over them (``a_error_seen_px``, ``b_error_seen_px``: what the camera can see of the
  person; the frames where any is seen), the share of landmarks hidden, and posed's mean visibility on the
  hidden landmarks and on the rest (``a_hidden``, ``b_hidden``). The target stays the ratio over all
  landmarks; the split says whether a miss is on what the camera sees or on what nobody could;
* **what the daemon makes of it**: each run goes on through what ``posed falls`` runs after the landmark stage
  (a fitter and a fall detector per person, the default config, the lens assumed): each person's eight
  flexions (knees, elbows, hips, shoulders) with the other in view against their fit alone, the mean
  |difference| over the frames both fitted (``flexion_vs_alone_deg``), and the ``falling``/``on_floor``
  messages raised with both in view (all, and those of A's, of B's and of anyone else's tracks) and in each
  one-person run (``fall_messages``; nobody falls in these scenes: she squats, he balances on one leg), and
  in the summary the crossings where the other's presence raised one that the person's run alone did not;
* **speed**: milliseconds per frame of the two-person and the one-person runs, landmark passes per frame.

With ``--crossings N`` the five fixed scenarios give way to N crossings drawn at random
(:func:`people_scenes.crossings`: in front and behind, both ways, random scales and paths), and ``summary``
counts the crossings that meet each target: one crossing's outcome turns on details a few pixels wide, so a
rate over many says more than any one of them.

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
from posed.landmarks import oks

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


FLEXIONS = ("theta_kn_l", "theta_kn_r", "theta_el_l", "theta_el_r", "theta_hp_l", "theta_hp_r", "theta_sh_l",
            "theta_sh_r")     # the fit's angles compared with and without the other person
DETECTING = ("falling", "on_floor")


def _watched(run: list) -> tuple[list[dict], list[tuple[int | None, str]]]:
    """What the daemon makes of a landmark run after the landmark stage (``posed falls``'s path, default
    config, the lens assumed: the scenes have no intrinsics): per frame, track id -> that person's FitResult
    (None: the frame's own person of a run that never saw two), and every fall message as (person, state)."""
    from posed.commands.falls import detect, fit_frames
    from posed.daemon.config import Config
    from posed.landmarks import RecordingHeader

    cfg = Config()
    header = RecordingHeader(scenes.CANVAS, 5.0, "bench people scene")
    fitted = list(fit_frames(cfg, header, (r.frame for r in run)))
    fits = [{res.extra.get("person"): res for res in (result, *others)} for _frame, result, others in fitted]
    messages = [(m.extra.get("person"), m.state) for _f, _r, msgs in detect(cfg, header, fitted) for m in msgs]
    return fits, messages


def _alone_a(a: scenes.Clip, b: scenes.Clip, scenario: scenes.Scenario, models_dir: Path | None) -> tuple:
    """A's one-person run of ``scenario``: (results, ms per frame, :func:`_watched` of it)."""
    run, ms, _ = _run(scenes.compose(a, b, scenario, "a")[0], models_dir)
    return run, ms, _watched(run)


def _fall_messages(watched: dict, ids: dict) -> dict:
    """``falling``/``on_floor`` messages: with both in view (all; and those of A's tracks, of B's, of anyone
    else), and in each one-person run. A track that was scored as A's on some frame counts as A's."""
    both = [pid for pid, state in watched["ab"][1] if state in DETECTING]
    a_ids, b_ids = {i for i in ids["a"] if i is not None}, {i for i in ids["b"] if i is not None}
    return {"with_both": len(both), "a": sum(1 for p in both if p in a_ids),
            "b": sum(1 for p in both if p in b_ids and p not in a_ids),
            "other": sum(1 for p in both if p not in a_ids and p not in b_ids),
            "a_alone": sum(1 for _p, state in watched["a"][1] if state in DETECTING),
            "b_alone": sum(1 for _p, state in watched["b"][1] if state in DETECTING)}


def _fit_of(fits: dict, tid: int | None, primary: int | None):
    """The FitResult of track ``tid`` in one frame's :func:`_watched` fits (None: the frame's own person, as a
    one-person run gives it); a frame before two people were ever seen names nobody, its fit is the primary's."""
    if tid is None:
        return fits.get(None) if None in fits else (next(iter(fits.values())) if len(fits) == 1 else None)
    return fits.get(tid) or (fits.get(None) if tid == primary else None)


def _flexion_gaps(mine, alone) -> list[float]:
    """|difference| (degrees) of each of ``FLEXIONS`` both fits measured."""
    if mine is None or alone is None or not (mine.ok and alone.ok):
        return []
    out = []
    for name in FLEXIONS:
        x, y = mine.angle(name), alone.angle(name)
        if x is not None and y is not None:
            out.append(abs(x - y))
    return out


def _assign(own: dict[str, np.ndarray | None], people: list[tuple[int, np.ndarray]]) -> dict[str, int | None]:
    """A and B to distinct people of the two-person frame (indices into ``people``; None: not found): of the
    pairings where each overlap with the person's own one-person run is at least ``MATCH_MIN``, the one whose
    overlaps sum highest. Matching one person first would score the other's track as theirs where they are
    hidden and the other covers the place they were."""
    score = {who: [oks(lms_own, lms, _size(lms_own)) if lms_own is not None else 0.0 for _tid, lms in people]
             for who, lms_own in own.items()}
    best, pick = -1.0, {"a": None, "b": None}
    for ia in [None, *range(len(people))]:
        for ib in [None, *range(len(people))]:
            if ia is not None and ia == ib:
                continue
            pair = {"a": ia, "b": ib}
            if any(i is not None and score[w][i] < MATCH_MIN for w, i in pair.items()):
                continue
            total = sum(score[w][i] for w, i in pair.items() if i is not None)
            if total > best:
                best, pick = total, pair
    return pick


def _covered(points: np.ndarray, cover: np.ndarray) -> np.ndarray:
    """Which of ``points`` (n, 2) canvas pixels fall on ``cover`` (height, width) bool."""
    xy = np.round(points).astype(int)
    inside = (xy[:, 0] >= 0) & (xy[:, 0] < cover.shape[1]) & (xy[:, 1] >= 0) & (xy[:, 1] < cover.shape[0])
    out = np.zeros(len(points), bool)
    out[inside] = cover[xy[inside, 1], xy[inside, 0]]
    return out


def _hidden(cov: list[np.ndarray], vis: list[np.ndarray]) -> dict:
    """Share of a person's truth landmarks hidden by the other person over the frames they were found with
    them, and posed's mean visibility on the hidden ones and on the rest."""
    if not cov:
        return {"share": None, "visibility_hidden": None, "visibility_seen": None}
    c, v = np.concatenate(cov), np.concatenate(vis)
    return {"share": round(float(c.mean()), 3),
            "visibility_hidden": round(float(v[c].mean()), 2) if c.any() else None,
            "visibility_seen": round(float(v[~c].mean()), 2) if (~c).any() else None}


def evaluate(scenario: scenes.Scenario, a: scenes.Clip, b: scenes.Clip, models_dir: Path | None,
             a_alone: tuple[list, float, tuple] | None = None) -> dict:
    """One scenario's row (see the module doc); ``a_alone``: A's one-person run (results, ms per frame,
    :func:`_watched` of it) when already made (A stands at the same place in every scenario)."""
    both, maps = scenes.compose(a, b, scenario, "ab")
    only_b, _ = scenes.compose(a, b, scenario, "b")
    cover = scenes.covers(a, b, scenario)
    run_ab, ms_ab, passes_ab = _run(both, models_dir)
    run_a, ms_a, watched_a = a_alone if a_alone is not None else _alone_a(a, b, scenario, models_dir)
    run_b, _, _ = _run(only_b, models_dir)
    watched = {"ab": _watched(run_ab), "a": watched_a, "b": _watched(run_b)}
    flex = {"a": [], "b": []}
    ids = {"a": [], "b": []}
    err = {"a_alone": [], "a_both": [], "b_dev": [], "b_alone": [], "b_both": [],
           "a_seen_alone": [], "a_seen_both": [], "b_seen_alone": [], "b_seen_both": []}
    hid = {"a": ([], []), "b": ([], [])}
    b_alone_at: dict[int, np.ndarray] = {}
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
                b_alone_at[k] = ref["b"][0][1][BODY12_IDX]
        people = _persons(run_ab[k])
        pick = _assign({w: ref[w][0][1] if ref[w] else None for w in ("a", "b")}, people)
        for who in ("a", "b"):
            if pick[who] is None:
                ids[who].append(None)
                continue
            tid, lms = people[pick[who]]
            ids[who].append(tid)
            found[f"{who}_both"] += 1
            flex[who] += _flexion_gaps(_fit_of(watched["ab"][0][k], tid, run_ab[k].primary),
                                       _fit_of(watched[who][0][k], None, None))
            own = ref[who][0][1]
            if who == "a":
                err["a_both"].append(_median_px(lms, truth_a))
                cov = _covered(truth_a, cover[k]["a"])
                hid["a"][0].append(cov)
                hid["a"][1].append(lms[:, 3])
                if (~cov).any():               # A's landmarks the camera sees, with B and alone
                    err["a_seen_both"].append(_median_px(lms[~cov], truth_a[~cov]))
                    err["a_seen_alone"].append(_median_px(own[~cov], truth_a[~cov]))
            else:
                err["b_dev"].append(_median_px(lms, own))
                if k in b_alone_at:           # B's error where both runs found him, with A and alone
                    mine = lms[BODY12_IDX]
                    err["b_both"].append(_median_px(mine, truth_b))
                    err["b_alone"].append(_median_px(b_alone_at[k], truth_b))
                    cov = _covered(truth_b, cover[k]["b"])
                    hid["b"][0].append(cov)
                    hid["b"][1].append(mine[:, 3])
                    if (~cov).any():
                        err["b_seen_both"].append(_median_px(mine[~cov], truth_b[~cov]))
                        err["b_seen_alone"].append(_median_px(b_alone_at[k][~cov], truth_b[~cov]))
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
        "a_error_seen_px": _ratio(err["a_seen_alone"], err["a_seen_both"]),
        "a_hidden": _hidden(*hid["a"]),
        "b_deviation_from_alone_px": round(float(np.nanmedian(err["b_dev"])), 1) if err["b_dev"] else None,
        "b_error_px": _ratio(err["b_alone"], err["b_both"]),
        "b_error_seen_px": _ratio(err["b_seen_alone"], err["b_seen_both"]),
        "b_hidden": _hidden(*hid["b"]),
        "flexion_vs_alone_deg": {who: round(float(np.mean(g)), 1) if g else None for who, g in flex.items()},
        "fall_messages": _fall_messages(watched, ids),
        "ms_per_frame": {"two_people": round(ms_ab, 1), "a_alone": round(ms_a, 1)},
        "landmark_passes_per_frame": round(passes_ab, 2),
    }


def summary(rows: list[dict]) -> dict:
    """Over the crossings of ``rows``: how many meet each scene target (the person hidden and the one in front
    within 1.2x of alone, on the frames scored; at most one identity switch per person), and how many have no
    identity switch at all."""
    out: dict = {}
    for kind, hidden, seen in (("front", "a", "b"), ("behind", "b", "a")):
        mine = [r for r in rows if r["scenario"].startswith("cross") and
                ("behind" in r["scenario"]) == (kind == "behind")]
        if not mine:
            continue

        def ratio(r: dict, who: str) -> float | None:
            return r["a_error_px"]["ratio"] if who == "a" else r["b_error_px"]["ratio"]

        within = {who: sum(1 for r in mine if ratio(r, who) is not None and ratio(r, who) <= 1.2)
                  for who in (hidden, seen)}
        out[kind] = {"crossings": len(mine), "hidden_within_1_2": within[hidden],
                     "in_front_within_1_2": within[seen],
                     "at_most_one_switch_each": sum(1 for r in mine if max(r["identity_switches"].values()) <= 1),
                     "without_switch": sum(1 for r in mine if max(r["identity_switches"].values()) == 0)}
        if all("fall_messages" in r for r in mine):
            gaps = {who: [r["flexion_vs_alone_deg"][who] for r in mine if r["flexion_vs_alone_deg"][who] is not None]
                    for who in (hidden, seen)}
            out[kind] |= {"with_fall_messages": sum(1 for r in mine if r["fall_messages"]["with_both"]),
                          "raised_by_the_other": sum(1 for r in mine if _raised_by_the_other(r["fall_messages"])),
                          "fall_messages_alone": sum(r["fall_messages"]["a_alone"] + r["fall_messages"]["b_alone"]
                                                     for r in mine),
                          "flexion_vs_alone_deg_median": {
                              "hidden": round(float(np.median(gaps[hidden])), 1) if gaps[hidden] else None,
                              "in_front": round(float(np.median(gaps[seen])), 1) if gaps[seen] else None}}
    return out


def _raised_by_the_other(m: dict) -> bool:
    """Whether someone got a fall message with the other person in view that their own one-person run did not
    give (or a message went to a track that was neither of them)."""
    return bool((m["a"] and not m["a_alone"]) or (m["b"] and not m["b_alone"]) or m["other"])


def run_bench(shared: Path, models_dir: Path | None = None, only: str = "", progress=lambda m: None,
              b_camera: str = scenes.B_CAMERA, crossings: int = 0, seed: int = 0) -> dict:
    """Every scenario (or ``only``), B cut from pose2sim's ``b_camera`` (cam03, the reported view, by default;
    cam01, cam02 and cam04 are the development views a change to the landmarker is tried on first); with
    ``crossings`` > 0, that many crossings drawn at random by ``seed`` (:func:`people_scenes.crossings`)
    instead of the five fixed scenarios."""
    a, b = scenes.load_clips(shared, b_camera)
    chosen = scenes.crossings(crossings, seed) if crossings > 0 else scenes.SCENARIOS
    chosen = [sc for sc in chosen if not only or only == sc.name]
    a_alone = None
    if len(chosen) > 1 and all(sc.a == chosen[0].a for sc in chosen):       # A alone: one run for all
        a_alone = _alone_a(a, b, chosen[0], models_dir)
    rows = []
    for sc in chosen:
        t0 = time.monotonic()
        rows.append(evaluate(sc, a, b, models_dir, a_alone))
        progress(f"{sc.name}: {time.monotonic() - t0:.1f} s")
    out = {"benchmark": "people", "canvas": list(scenes.CANVAS), "b_camera": b_camera, "scenarios": rows,
           "summary": summary(rows),
           "targets": {"a_error_ratio_max": 1.2, "switches_apart": 0, "switches_per_occluded_crossing_max": 1}}
    if crossings > 0:
        out["crossings"] = {"n": crossings, "seed": seed}
    return out
