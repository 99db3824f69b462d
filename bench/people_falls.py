"""Falls with a bystander (issue 36): the synthetic fall scenarios with a second person in the room.

Every scenario of a split (``bench.falls_scenarios.catalogue``, robot mount) is rendered again with a second,
taller person (1.80 m; the faller is 1.65 m) through the same camera, doing one of:

* ``standing``: standing still 1.2 m to the faller's side, facing the camera;
* ``walking``: walking across the room behind the faller and back;
* ``kneeling``: standing to the side until a second after the impact (from the start for a daily activity),
  then walking to the faller and kneeling beside them to the end (the faller then lies 5 s longer, so the
  kneeling has time to end the event or to raise a second one).

The bystander is given to scenarios in turn (standing, walking, kneeling, ...), so each kind meets every sort
of fall and view. Per frame both people's landmarks (projected, 1 % noise, as the one-person benchmark's) go
through :class:`landmarks.tracks.PersonTracker` with the daemon's landmark slots (:mod:`bench.people_tracks`),
each track is fitted by a fitter of its own (video mode), and the fits go to
:class:`falls.people.PeopleFalls` with the frame's own person first (the track followed longest, as the daemon
does). Which track is whom is read off the landmarks each was given (identity from the renderer, not from the
tracker). Counted:

* **recall**: falls with a ``falling`` or ``on_floor`` message for the faller's track; **false alarms**: daily
  activities with any message; **bystander events**: any message for the bystander's track;
* **second events**: falls with more than one event id for the faller; **ended**: falls whose event got a
  ``recovered`` message (the faller never gets up in these scenarios);
* **identity switches**: changes of the track id given to each person between consecutive frames where they
  were seen;
* the same scenarios alone (one person, the same fits path), to compare;
* **the faller's 3D**: PA-MPJPE (mm) of the fit's 12 body joints against the renderer's, on the frames where
  the bystander's body covers some of the faller's landmarks (:mod:`bench.people_occlusion`; moved only with
  ``occlude``) and on the others; paired over the frames the run with the bystander and the run alone both
  fitted (``faller_3d_same_frames_mm``);
* **who is who** (with the bystander): the faller is the household's one member (``falls.household``, their true
  height); at the end, how each person was recognised (the member, a visitor, not known), and in how many of the
  frames with the faller in view the history followed the faller, or the bystander.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from posed.bench import people_occlusion as occlusion
from posed.bench.falls import DETECTING_STATES as DETECTING
from posed.bench.falls_body import Body
from posed.bench.falls_scenarios import STAND, Key, Scenario, catalogue, frames, kneel, truth_result, walk
from posed.bench.ood import pa_mpjpe
from posed.bench.people_tracks import NamedBodies, switches
from posed.daemon.stages.fit import mount_gravity
from posed.falls.config import FallsConfig, HouseholdMember
from posed.falls.detector import FallDetector
from posed.falls.people import PeopleFalls
from posed.fitting import JOINT_3D_NAMES, FitResult

BYSTANDERS = ("standing", "walking", "kneeling")
BYSTANDER_HEIGHT_M = 1.80
SIDE_M = 1.2              # the standing bystander's offset to the faller's side
LIE_LONGER_S = 5.0        # the faller lies this much longer when a bystander kneels beside them
KNEEL_GAP_M = 0.7         # the kneeling bystander's pelvis from the faller's, across the floor
KNEEL_AT = ("side", "camera")
BODY12_NAMES = JOINT_3D_NAMES[1:]   # the fit's 12 body joints (the mid-hip origin left out)


@dataclass(frozen=True)
class TwoPeople:
    """A faller's scenario, the bystander's (same camera, fps and duration) and what the bystander does."""

    faller: Scenario
    bystander: Scenario
    kind: str


def _facing_camera(pose):
    return pose.with_(yaw=180.0)


def _hold(keys: list[Key], until: float) -> list[Key]:
    return keys if keys[-1].t >= until else keys + [Key(until, keys[-1].pose, seat=keys[-1].seat, ease="hold",
                                                        xy=keys[-1].xy)]


def with_bystander(sc: Scenario, kind: str, kneel_at: str = "side") -> TwoPeople:
    """``sc`` with a second person doing ``kind`` (module doc); a kneeling bystander kneels at the faller's
    ``side`` (across the room from where they stood) or on the ``camera``'s side of them, between the camera and
    the person who fell."""
    if kind not in BYSTANDERS:
        raise ValueError(f"bystander {kind!r} is not one of: {', '.join(BYSTANDERS)}")
    if kneel_at not in KNEEL_AT:
        raise ValueError(f"kneel_at {kneel_at!r} is not one of: {', '.join(KNEEL_AT)}")
    faller = sc
    x0, y0 = sc.start_xy
    side = -1.0 if x0 > 0 else 1.0
    home = (x0 + side * SIDE_M, y0 + 0.3)
    if kind == "kneeling":
        faller = replace(sc, keys=_hold(sc.keys, sc.duration + LIE_LONGER_S))
    end = faller.duration
    if kind == "standing":
        keys = [Key(0.0, _facing_camera(STAND), xy=home), Key(end, _facing_camera(STAND), xy=home, ease="hold")]
    elif kind == "walking":
        far = (x0 - side * SIDE_M, y0 + 1.0)
        keys, _ = walk([home, (home[0], y0 + 1.0), far, (home[0], y0 + 1.0)], speed=0.8)
        keys = _hold(keys, end)
    else:
        lying = _lying_point(faller)
        t_go = (sc.truth.t_impact + 1.0) if sc.truth.kind == "fall" and sc.truth.t_impact else 0.5
        if kneel_at == "camera":
            to_cam = np.array([sc.camera.x, sc.camera.y]) - lying[:2]
            target = tuple(float(v) for v in lying[:2] + KNEEL_GAP_M * to_cam / max(np.linalg.norm(to_cam), 1e-9))
        else:
            target = (float(lying[0] + side * KNEEL_GAP_M), float(lying[1] + 0.2))
        approach, _ = walk([home, target], speed=0.8, start_pause=0.0)
        approach = [replace(k, t=k.t + t_go) for k in approach]
        toward = math.degrees(math.atan2(-(lying[0] - target[0]), lying[1] - target[1]))
        kneel_keys, _ = kneel(1.0, hold=end)
        t_kneel = approach[-1].t
        down = [replace(k, t=k.t - 1.5 + t_kneel, pose=k.pose.with_(yaw=toward), xy=None)
                for k in kneel_keys[2:4]]          # standing -> one knee -> both knees, then held
        keys = [Key(0.0, _facing_camera(STAND), xy=home), Key(t_go, _facing_camera(STAND), xy=home, ease="hold")]
        keys += approach[1:] + down
        keys = _hold(keys, end)
    by = Scenario(name=f"{sc.name}+{kind}", kind="adl", keys=keys, truth=sc.truth, camera=sc.camera,
                  body=Body(BYSTANDER_HEIGHT_M), fps=sc.fps, noise_frac=sc.noise_frac, seed=sc.seed + 7919,
                  start_xy=home)
    return TwoPeople(faller, by, kind)


def _lying_point(sc: Scenario) -> np.ndarray:
    last = list(frames(sc))[-1].joints_world
    return 0.5 * (last["left_hip"][:2] + last["right_hip"][:2])


def cases(split: str = "heldout", kneel_at: str = "side") -> list[TwoPeople]:
    """Every scenario of ``split`` with a bystander, the kinds given in turn (``kneel_at``: with_bystander)."""
    return [with_bystander(sc, BYSTANDERS[i % len(BYSTANDERS)], kneel_at) for i, sc in enumerate(catalogue(split))]


def _fitter_factory(kind: str) -> Callable[[], Callable]:
    """A new per-person ``fit(landmarks, seq, t, size, intrinsics, frame, camera, gravity)``: the real fitter
    (video mode; ``gravity`` what the daemon's fitting stage gives it, daemon.stages.fit.frame_gravity) or
    ``truth`` (a perfect fit from the renderer's joints, for tests of the detector path)."""
    if kind == "truth":
        def make_truth():
            return lambda lm, seq, t, size, intr, frame, cam, gravity=None: truth_result(frame, cam)
        return make_truth
    from posed.fitting import FitConfig, Fitter

    pool: list = []

    def make_real():
        fitter = pool.pop() if pool else Fitter(FitConfig())
        fitter.reset()
        fitter.forget_body()          # a new person: not the proportions the pooled fitter learned of another

        def fit(lm, seq, t, size, intr, frame, cam, gravity=None):
            return fitter.fit(lm, seq, t, size, mode="video", intrinsics=intr, gravity=gravity)
        fit.release = lambda: pool.append(fitter)  # type: ignore[attr-defined]
        return fit
    return make_real


def _hidden_masks(case: TwoPeople, f_frame, b_frame) -> dict[str, np.ndarray]:
    """Which of each person's 33 landmarks the other's body covers in this frame (:func:`bench.people_occlusion.hidden`),
    by ``faller`` and ``bystander``."""
    cam = case.faller.camera
    bodies = {"faller": case.faller.body, "bystander": case.bystander.body}
    points = {"faller": occlusion.body_points(f_frame.joints_world, cam),
              "bystander": occlusion.body_points(b_frame.joints_world, cam)}
    return {who: occlusion.hidden(occlusion.landmark_points(points[who]), points[other], bodies[other].height)
            for who, other in (("faller", "bystander"), ("bystander", "faller"))}


def hidden_masks(case: TwoPeople) -> dict[int, dict[str, np.ndarray]]:
    """Per frame (seq) with both people drawn, :func:`_hidden_masks`: rendered and computed once per case, for
    the runs with the bystander (moved with ``occlude``) and alone, which are then scored on the same frames."""
    return {f.seq: _hidden_masks(case, f, b)
            for f, b in zip(frames(case.faller), frames(case.bystander), strict=False)
            if f.landmarks is not None and b.landmarks is not None}


def faller_covered(hidden: dict[int, dict[str, np.ndarray]]) -> dict[int, bool]:
    """Per frame of :func:`hidden_masks`: whether the bystander's body covers any of the faller's landmarks."""
    return {seq: bool(masks["faller"].any()) for seq, masks in hidden.items()}


def faller_error_mm(result: FitResult, f_frame, camera) -> float | None:
    """PA-MPJPE (mm) of the fit's 12 body joints against the rendered body's (camera axes), None without a 3D fit."""
    if not result.ok or not all(name in result.joints_3d for name in BODY12_NAMES):
        return None
    truth = occlusion.body_points(f_frame.joints_world, camera)
    est = np.array([result.joints_3d[name] for name in BODY12_NAMES], float)
    return 1000.0 * pa_mpjpe(est, np.array([truth[name] for name in BODY12_NAMES]))


def _occluded(case: TwoPeople, given: list, hidden: dict[int, dict[str, np.ndarray]],
              occluders: dict[str, occlusion.Occluder], hidden_share: list[float]) -> list:
    """``given`` (seq, t, faller frame, bystander frame) with each person's landmarks that the other's body
    covers (``hidden``: :func:`hidden_masks`) moved as the landmark stage moves them
    (:mod:`bench.people_occlusion`); the faller's share of hidden landmarks per frame with both in view appended
    to ``hidden_share``."""
    cam = case.faller.camera
    bodies = {"faller": case.faller.body, "bystander": case.bystander.body}
    out = []
    for seq, t, f_frame, b_frame in given:
        if b_frame is None or f_frame.landmarks is None or b_frame.landmarks is None:
            out.append((seq, t, f_frame, b_frame))
            continue
        frames_now = {"faller": f_frame, "bystander": b_frame}
        covered = hidden[seq]
        hidden_share.append(float(covered["faller"].mean()))
        moved = {}
        for who, fr in frames_now.items():
            lm = occluders[who].apply(fr.landmarks, covered[who], occlusion.size_px(fr.joints_world, cam, bodies[who]),
                                      1.0 / case.faller.fps)
            moved[who] = replace(fr, landmarks=lm)
        out.append((seq, t, moved["faller"], moved["bystander"]))
    return out


def run_case(case: TwoPeople, make_fit: Callable[[], Callable], cfg: FallsConfig, alone: bool = False,
             occlude: bool = False, hidden: dict[int, dict[str, np.ndarray]] | None = None) -> dict:
    """One scenario through the tracker, a fitter per track and :class:`PeopleFalls` (``alone``: the faller
    only; ``occlude``: each person's landmarks the other covers as the landmark stage gives them,
    :mod:`bench.people_occlusion`). ``hidden`` (:func:`hidden_masks`, computed when not given): what each
    body covers of the other, and the frames the faller's 3D error is scored on, split by whether the
    bystander's body covers them; the row's ``_faller_3d_by_seq`` (seq -> mm) is for :func:`run_bench`'s
    pairing, which removes it."""
    if hidden is None:
        hidden = hidden_masks(case)
    covered = faller_covered(hidden)
    cam = case.faller.camera
    size, intr = (cam.width, cam.height), cam.intrinsics
    given = [(f.seq, f.t, f, None) for f in frames(case.faller)]
    if not alone:
        by = list(frames(case.bystander))
        given = [(f.seq, f.t, f, by[i] if i < len(by) else None) for i, (_, _, f, _) in enumerate(given)]
    hidden_share: list[float] = []
    if occlude and not alone:
        seed = case.faller.seed
        given = _occluded(case, given, hidden,
                          {"faller": occlusion.Occluder(seed), "bystander": occlusion.Occluder(seed + 1)},
                          hidden_share)
    bodies = NamedBodies()
    if not alone:         # who is who: the person who falls is the household's member (their true height)
        cfg = replace(cfg, household=(HouseholdMember("resident", case.faller.body.height),))
    detectors = PeopleFalls(FallDetector(replace(cfg), "bench"))
    down = mount_gravity(cfg)     # a measured mount's down, given to the fit as the daemon gives it
    followed: list[str | None] = []
    fits: dict[int, Callable] = {}
    ids: dict[str, list[int]] = {"faller": [], "bystander": []}
    messages = []
    by_seq: dict[int, float] = {}
    for seq, t, f_frame, b_frame in given:
        seen = [(who, fr) for who, fr in (("faller", f_frame), ("bystander", b_frame))
                if fr is not None and fr.landmarks is not None]
        track_ids = bodies.update(t, [(who, fr.landmarks) for who, fr in seen])
        people = []
        for (who, fr), tid in zip(seen, track_ids, strict=True):
            ids[who].append(tid)
            fit = fits.get(tid) or fits.setdefault(tid, make_fit())
            r = fit(fr.landmarks, seq, t, size, intr, fr, cam, down)
            if who == "faller" and seq in covered:
                e = faller_error_mm(r, fr, cam)
                if e is not None:
                    by_seq[seq] = e
            people.append((tid, replace(r, extra={**r.extra, "person": tid}), fr.landmarks))
        if people:
            main = bodies.tracker.longest_followed([p[0] for p in people])
            people.sort(key=lambda p: p[0] != main)
        else:
            people = [(None, FitResult.failure(seq, t, "no person"), None)]
        messages += detectors.update(people, t, seq, size, intr)
        key = detectors.followed()
        followed.append(next((w for (w, _), tid in zip(seen, track_ids, strict=True) if tid == key), None)
                        if "faller" in [w for w, _ in seen] else "absent")
    for fit in fits.values():
        getattr(fit, "release", lambda: None)()
    faller_ids, by_ids = set(ids["faller"]), set(ids["bystander"])
    mine = [m for m in messages if m.extra.get("person") in faller_ids]
    theirs = [m for m in messages if m.extra.get("person") in by_ids - faller_ids]
    first = next((m for m in mine if m.state in DETECTING), None)
    truth = case.faller.truth
    latency = None
    if first is not None and truth.kind == "fall":
        latency = round(first.t_detect - (truth.t_impact or 0.0), 3)
    return {"name": case.faller.name, "kind": truth.kind, "bystander": "alone" if alone else case.kind,
            "detected": first is not None, "latency_s": latency,
            "states": [f"{m.extra.get('person')}:{m.state}" for m in messages],
            "bystander_events": len(theirs), "event_ids": len({m.id for m in mine}),
            "ended": any(m.state == "recovered" for m in mine),
            "switches": {w: switches(v) for w, v in ids.items()}, "rematches": detectors.rematches,
            "faller_hidden": _hidden_summary(hidden_share) if occlude and not alone else None,
            "faller_3d_mm": {part: {"frames": len(v), "sum": round(float(np.sum(v)), 1)}
                             for part, v in _by_cover(covered, by_seq).items()},
            "_faller_3d_by_seq": by_seq,
            "household": None if alone else _recognition(detectors, ids, followed)}


def _hidden_summary(shares: list[float]) -> dict:
    """The faller's landmarks the bystander covered: frames with any hidden, frames on which that made them not
    found, and the mean share on the frames with any."""
    some = [x for x in shares if x > 0]
    return {"frames_both": len(shares), "frames_some_hidden": len(some),
            "frames_lost": sum(x >= occlusion.LOST_SHARE for x in shares),
            "mean_share_hidden": round(float(np.mean(some)), 3) if some else 0.0}


def _recognition(detectors: PeopleFalls, ids: dict[str, list[int]], followed: list) -> dict:
    """How the faller (the member) and the bystander were recognised at the end, and whom the history followed
    while the faller was in view (``faller``, ``bystander`` or None: nobody, only visitors)."""
    def last(who):
        return detectors.household.who(ids[who][-1]) if ids[who] else None

    f, b = last("faller"), last("bystander")
    shown = [x for x in followed if x != "absent"]
    return {"faller": None if f is None else f["member"] or ("visitor" if f["visitor"] else "unknown"),
            "bystander": None if b is None else b["member"] or ("visitor" if b["visitor"] else "unknown"),
            "followed_faller": sum(x == "faller" for x in shown), "followed_bystander": sum(x == "bystander" for x in shown),
            "frames_faller_in_view": len(shown)}


def summarise(rows: list[dict]) -> dict:
    falls = [r for r in rows if r["kind"] == "fall"]
    adl = [r for r in rows if r["kind"] != "fall"]
    lat = sorted(r["latency_s"] for r in falls if r["latency_s"] is not None)
    return {"falls": len(falls), "recall": round(sum(r["detected"] for r in falls) / len(falls), 3) if falls else None,
            "adl": len(adl), "false_alarms": sum(r["detected"] or bool(r["states"]) for r in adl),
            "bystander_events": sum(r["bystander_events"] for r in rows),
            "second_events": sum(r["event_ids"] > 1 for r in falls),
            "ended": sum(r["ended"] for r in falls),
            "identity_switches": sum(r["switches"]["faller"] + r["switches"]["bystander"] for r in rows),
            "median_latency_s": lat[len(lat) // 2] if lat else None, **_recognised(rows), **_covered(rows),
            "faller_3d_mm": _faller_3d(rows)}


def _faller_3d(rows: list[dict]) -> dict:
    """The faller's mean PA-MPJPE (mm) over the frames the fit answered, those with some landmark covered by the
    bystander's body and the others (each row's ``faller_3d_mm``)."""
    out = {}
    for part in ("covered", "clear"):
        n = sum(r["faller_3d_mm"][part]["frames"] for r in rows)
        total = sum(r["faller_3d_mm"][part]["sum"] for r in rows)
        out[part] = {"frames": n, "mean": round(total / n, 1) if n else None}
    return out


def _by_cover(covered: dict[int, bool], values: dict) -> dict[str, list]:
    """``values`` (by frame seq) in frame order, split by whether the bystander's body covers the faller there."""
    out: dict[str, list] = {"covered": [], "clear": []}
    for seq in sorted(values):
        out["covered" if covered[seq] else "clear"].append(values[seq])
    return out


def _covered(rows: list[dict]) -> dict:
    hid = [r["faller_hidden"] for r in rows if r.get("faller_hidden")]
    if not hid:
        return {}
    return {"faller_frames_with_both": sum(h["frames_both"] for h in hid),
            "faller_frames_partly_hidden": sum(h["frames_some_hidden"] for h in hid),
            "faller_frames_lost": sum(h["frames_lost"] for h in hid),
            "cases_faller_partly_hidden": sum(h["frames_some_hidden"] > 0 for h in hid)}


def _recognised(rows: list[dict]) -> dict:
    hh = [r["household"] for r in rows if r.get("household")]
    if not hh:
        return {}
    return {"faller_as_member": sum(h["faller"] == "resident" for h in hh),
            "bystander_as_visitor": sum(h["bystander"] == "visitor" for h in hh),
            "bystander_as_member": sum(h["bystander"] == "resident" for h in hh),
            "history_on_bystander_frames": sum(h["followed_bystander"] for h in hh),
            "history_on_faller_frames": sum(h["followed_faller"] for h in hh),
            "faller_in_view_frames": sum(h["frames_faller_in_view"] for h in hh), "cases": len(hh)}


def run_bench(split: str = "heldout", fit_kind: str = "real", cfg: FallsConfig | None = None, only: str = "",
              progress=lambda m: None, occlude: bool = False, kneel_at: str = "side") -> dict:
    """Each scenario with its bystander and alone; the summaries per bystander kind and together (``occlude``,
    ``kneel_at``: :func:`run_case`, :func:`with_bystander`)."""
    cfg = cfg or FallsConfig()
    t0 = time.monotonic()
    make_fit = _fitter_factory(fit_kind)
    rows_by, rows_alone = [], []
    paired: dict[str, list[tuple[float, float]]] = {"covered": [], "clear": []}
    for case in cases(split, kneel_at):
        if only and only not in case.faller.name:
            continue
        cfg_case = replace(cfg, camera_tilt_deg=case.faller.camera.tilt, camera_height_m=case.faller.camera.z,
                           camera_geometry="measured")
        hidden = hidden_masks(case)
        rows_by.append(run_case(case, make_fit, cfg_case, occlude=occlude, hidden=hidden))
        rows_alone.append(run_case(case, make_fit, cfg_case, alone=True, hidden=hidden))
        with_by, alone = rows_by[-1].pop("_faller_3d_by_seq"), rows_alone[-1].pop("_faller_3d_by_seq")
        both = {seq: (with_by[seq], alone[seq]) for seq in with_by.keys() & alone.keys()}
        for part, v in _by_cover(faller_covered(hidden), both).items():
            paired[part] += v
        r = rows_by[-1]
        progress(f"{r['name']} + {r['bystander']}: detected {r['detected']}, states {r['states']}")
    return {"split": split, "fit": fit_kind, "geometry": "given (the scene's camera height and tilt)",
            "occlusion": occlude, "kneel_at": kneel_at,
            "with_bystander": summarise(rows_by), "alone": summarise(rows_alone),
            "per_bystander": {k: summarise([r for r in rows_by if r["bystander"] == k]) for k in BYSTANDERS},
            "faller_3d_same_frames_mm": {part: {"frames": len(v),
                                                "with_bystander": round(float(np.mean([x[0] for x in v])), 1) if v else None,
                                                "alone": round(float(np.mean([x[1] for x in v])), 1) if v else None}
                                         for part, v in paired.items()},
            "scenarios": rows_by, "seconds": round(time.monotonic() - t0, 1),
            "targets": {"recall": "as alone (1.0)", "false_alarms": "as alone (0)", "second_events": 0, "ended": 0}}
