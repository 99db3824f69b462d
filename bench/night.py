"""``posed bench night``: posed's landmark stage on colour images in dim light, and on what an infrared imager gives.

Sources (real, from the shared data): the squat video (65 frames, 5 fps), the four pose2sim balancing views
(60 fps, thinned to the daemon's ``pipeline.target_fps`` as its capture stage thins them: every 6th frame at
10 fps), and three still images (pose.jpg, the sitting woman, COCO 785), each a clip of one frame.

Every frame goes through the landmark stage as the daemon runs it: the daemon's config (``landmarks`` section:
:class:`landmarks.MultiPoseLandmarker` when ``max_people`` > 1, video-mode tracking, its one-euro filters), a
frame larger than ``pipeline.frame_max_pixels`` scaled down by the whole factor the capture stage uses
(``hal.downscale``) and the landmarks put back in the source's pixels, timestamps ``i / fps``; a fresh tracker
for every clip and condition. Conditions (:func:`conditions`; image models in :mod:`bench.night_sensor`):

* ``colour``: the original (the reference);
* ``colour f=1/N``: the colour camera in 1/N of the light (``night_sensor.dim``; N = 1, 2, 4, ... 512);
* ``gray``: BT.601 luma on three channels (what an infrared imager gives of a lit scene);
* ``gray+dots xK``: with the projector's ~5,000 dots peaking at K times the frame's mean luma;
* ``gray f=1/N``: the grayscale image through the same sensor model (an infrared image at a lower level; the
  D435's infrared pixel is 3 um, larger than the colour camera's 1.4 um, so this is pessimistic);
* ``gray f=1/N+dots xK``: a dark room with the projector on: the grayscale image at 1/N of the light, then
  each dot added at a peak of K times the *lit* grayscale image at that pixel (a dot shows the surface's
  reflectance, as the room's light did; the projector's light does not dim with the room's, and the camera's
  gain, set by the dark scene, is not applied to it);
* ``colour f=1/N +gain``, ``gray f=1/N +gain``: the same frames as ``colour f=1/N`` / ``gray f=1/N`` (the same
  seed: the same noise), each frame given a gain before the landmark stage sees it (:mod:`bench.night_gain`, on
  the 8-bit values: measured, not adopted); ``+gain linear``: the gain in linear light instead. Every other
  condition shows the stage the frames as they come. ``--only`` runs some conditions (and the original), each on the frames
  it draws in the whole list.

Sources ``untouched`` (``--sources untouched``): the multi-person clips of the shared data, never looked at while
the gain was made (:data:`UNTOUCHED`, thinned to ``pipeline.target_fps`` as the videos above), under
:func:`untouched_conditions`; the main person as above.

Metrics per source and condition, against the colour original: of the frames where the original found the
person (the person with the longest torso in the frame, the main person), those where the condition found
them (a person whose box over the fit's 12 body landmarks, ``fitting.BODY_LANDMARKS``, overlaps the
original's with IoU >= ``MATCH_IOU``); the 2D deviation of those 12 landmarks from the original's on the found
frames, median and p90, in source pixels and over the original's torso length (mid-shoulder to mid-hip) that
frame; the median of the frames' mean luma (``night_sensor.mean_luma``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from posed.bench import night_sensor as ns

MATCH_IOU = 0.3
LIGHT = tuple(2.0 ** -k for k in range(12))          # 1 ... 1/2048
GRAY_LIGHT = (1 / 32, 1 / 128)
DOT_LEVELS = (0.5, 2.0)
DARK_DOTS = ((1 / 512, 1.0),)                          # (light, dots' level over the lit original's mean luma)
GAIN_LIGHT = tuple(2.0 ** -k for k in range(7, 12))   # 1/128 ... 1/2048: around the loss
OTHER_GAIN_LIGHT = GAIN_LIGHT                           # the gain in linear light, beside the default's
GRAY_GAIN_LIGHT = (1 / 128,)
SEED = 20261207
VIDEOS = (("squat", Path("reference/tfjs_pose_squats/pose_squats.mp4")),
          *((f"balancing {c}", Path(f"reference/pose2sim_demo/balancing/{c}.mp4"))
            for c in ("cam01", "cam02", "cam03", "cam04")))
UNTOUCHED = (("s2d_enter", Path("reference/multi_person/s2d_enter.mp4")),
             ("bend_hand", Path("reference/multi_person/bend_hand.mp4")))
IMAGES = (Path("reference/mediapipe_pose_jpg/pose.jpg"), Path("reference/mediapipe_samples_ios_sitting/test_image.jpg"),
          Path("images/coco_cc_by/coco_val2017_000000000785.jpg"))


@dataclass(frozen=True)
class Condition:
    name: str
    kind: str          # "colour", "dim", "gray", "dots", "gray_dim", "dark_dots"
    value: float       # the light fraction (dim, gray_dim, dark_dots) or the dots' level (dots); 1 otherwise
    level: float = 0.0  # dark_dots: the dots' peak over the lit original's mean luma
    gain: str = ""      # the dim-frame gain before the stage: "" off, "linear" or "srgb" (bench.night_gain)

    @property
    def base(self) -> str:
        """The condition whose frames (and seed) a ``+gain`` condition shares: its name without the gain."""
        return self.name.split(" +gain")[0]


def gained(cond: Condition, space: str = "") -> Condition:
    """``cond`` with the gain on: in ``space`` (default ``bench.night_gain.SPACE``, named ``+gain``; the other
    space is named ``+gain SPACE``)."""
    from posed.bench.night_gain import SPACE as default

    space = space or default
    return Condition(f"{cond.name} +gain" + ("" if space == default else f" {space}"), cond.kind, cond.value,
                     cond.level, space)


def conditions(light: tuple[float, ...] = LIGHT, gray_light: tuple[float, ...] = GRAY_LIGHT,
               dot_levels: tuple[float, ...] = DOT_LEVELS,
               dark_dots: tuple[tuple[float, float], ...] = DARK_DOTS, gain_light: tuple[float, ...] = GAIN_LIGHT,
               other_gain_light: tuple[float, ...] = OTHER_GAIN_LIGHT,
               gray_gain_light: tuple[float, ...] = GRAY_GAIN_LIGHT) -> list[Condition]:
    """The conditions in order (the ``+gain`` ones last, so the others keep their seeds)."""
    out = [Condition("colour", "colour", 1.0)]
    out += [Condition(f"colour f=1/{round(1 / f)}", "dim", f) for f in light]
    out.append(Condition("gray", "gray", 1.0))
    out += [Condition(f"gray+dots x{k:g}", "dots", k) for k in dot_levels]
    out += [Condition(f"gray f=1/{round(1 / f)}", "gray_dim", f) for f in gray_light]
    out += [Condition(f"gray f=1/{round(1 / f)}+dots x{k:g}", "dark_dots", f, k) for f, k in dark_dots]
    out += [gained(Condition(f"colour f=1/{round(1 / f)}", "dim", f)) for f in gain_light]
    out += [gained(Condition(f"colour f=1/{round(1 / f)}", "dim", f), "linear") for f in other_gain_light]
    out += [gained(Condition(f"gray f=1/{round(1 / f)}", "gray_dim", f)) for f in gray_gain_light]
    out += [gained(Condition(f"gray f=1/{round(1 / f)}", "gray_dim", f), "linear") for f in gray_gain_light]
    return out


def untouched_conditions() -> list[Condition]:
    """For the untouched clips: the original, colour from 1/64 down (just above the gain's threshold and
    below) with and without the gain, and gray at 1/128 with and without it."""
    light = tuple(2.0 ** -k for k in range(6, 12))
    return conditions(light=light, gray_light=GRAY_GAIN_LIGHT, dot_levels=(), dark_dots=())


def transform(cond: Condition, seed: int, shape: tuple[int, int]) -> Callable[[np.ndarray], tuple[np.ndarray, float]]:
    """A function image -> (the condition's image, its mean luma) for one clip (its random state and dots)."""
    rng = np.random.default_rng(seed)
    pattern = ns.dot_pattern(shape[0], shape[1], seed) if cond.kind in ("dots", "dark_dots") else None

    def apply(image: np.ndarray) -> tuple[np.ndarray, float]:
        if cond.kind == "colour":
            out = image
        elif cond.kind == "dim":
            out = ns.dim(image, cond.value, rng).image
        elif cond.kind == "gray":
            out = ns.gray(image)
        elif cond.kind == "dots":
            out = ns.with_dots(ns.gray(image), pattern, cond.value)
        elif cond.kind in ("gray_dim", "dark_dots"):
            lit = ns.gray(image)
            out = np.repeat(ns.dim(lit[:, :, :1], cond.value, rng).image, 3, axis=2)
            if cond.kind == "dark_dots":     # the projector's light does not dim with the room's
                spots = cond.level * lit[:, :, 0].astype(np.float32) * pattern
                out = np.clip(np.rint(out + spots[:, :, None]), 0, 255).astype(np.uint8)
        else:
            raise ValueError(f"unknown condition kind {cond.kind!r}")
        return out, ns.mean_luma(out)

    return apply


# -- sources ---------------------------------------------------------------------------------------------------

@dataclass
class Clip:
    source: str            # the row's name (several clips may share it: the still images)
    name: str
    fps: float
    frames: list[tuple[int, np.ndarray]]     # (frame index in the video, BGR image)


def read_video(path: Path, target_fps: float, limit: int | None = None) -> Clip:
    """The frames the daemon's capture stage takes at ``target_fps`` (every round(fps / target_fps)-th)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    fps = cap.get(cv2.CAP_PROP_FPS) or 30.0
    step = max(1, round(fps / target_fps))
    frames, i = [], 0
    try:
        while limit is None or len(frames) < limit:
            ok, image = cap.read()
            if not ok:
                break
            if i % step == 0:
                frames.append((i, image))
            i += 1
    finally:
        cap.release()
    if not frames:
        raise RuntimeError(f"{path}: no frame could be read")
    return Clip(path.stem, path.name, float(fps), frames)


def clips(shared: Path, target_fps: float, quick: int | None = None, sources: str = "dev") -> list[Clip]:
    """The sources (module docstring); ``quick``: only the squat video's first ``quick`` frames (``dev``) or
    the first untouched clip's (``untouched``)."""
    import cv2

    if sources not in ("dev", "untouched"):
        raise ValueError(f"sources must be dev or untouched, got {sources!r}")
    if sources == "untouched":
        out = []
        for source, rel in UNTOUCHED[:1] if quick else UNTOUCHED:
            clip = read_video(shared / rel, target_fps, quick)
            clip.source = source
            out.append(clip)
        return out
    if quick:
        clip = read_video(shared / VIDEOS[0][1], target_fps, quick)
        clip.source = VIDEOS[0][0]
        return [clip]
    out = []
    for source, rel in VIDEOS:
        clip = read_video(shared / rel, target_fps)
        clip.source = source
        out.append(clip)
    for rel in IMAGES:
        image = cv2.imread(str(shared / rel))
        if image is None:
            raise RuntimeError(f"{shared / rel}: not readable")
        out.append(Clip("images (3)", rel.name, 1.0, [(0, image)]))
    return out


# -- the landmark stage, as the daemon runs it -----------------------------------------------------------------

class Stage:
    """The daemon's landmark stage on frames of a source image size (scale down, landmarks back in source px)."""

    def __init__(self, config) -> None:
        from posed.landmarks import MultiPoseLandmarker, PoseLandmarker

        self.config = config
        cfg = config.landmarks
        self.landmarker = MultiPoseLandmarker(cfg) if cfg.max_people > 1 else PoseLandmarker(cfg)
        self.landmarker.warmup()

    def run(self, images: Iterator[tuple[int, np.ndarray]], fps: float, gain: str = "",
            gains: list[float] | None = None, after: list[float] | None = None) -> list[list[np.ndarray]]:
        """Each frame's people (a list of (33, 5) landmark arrays in source pixels; empty: nobody). The tracker
        starts afresh (``reset``: what the daemon's stage does when a source starts again). ``gain``: the
        dim-frame gain put on each frame before the stage sees it (``bench.night_gain.LowLight`` in that space;
        "" = off); each frame's gain is added to ``gains``
        and the mean luma of the image the models saw to ``after``."""
        from posed.bench.night_gain import LowLight
        from posed.hal import downscale, mean_luma, scale_factor

        self.landmarker.reset()
        low_light = LowLight(space=gain) if gain else None
        out = []
        for seq, (index, image) in enumerate(images):
            h, w = image.shape[:2]
            k = scale_factor(w, h, self.config.pipeline.frame_max_pixels)
            small = downscale(image, k)
            seen, g = low_light.apply(small) if low_light is not None else (small, 1.0)
            frame = self.landmarker.process(seen, index / fps, seq)
            if gains is not None:
                gains.append(g)
            if after is not None:
                after.append(mean_luma(seen))
            people = ([p.landmarks for p in frame.people] if frame.people
                      else [] if frame.landmarks is None else [frame.landmarks])
            scaled = []
            for lm in people:
                lm = np.array(lm, dtype=np.float64, copy=True)
                lm[:, :3] *= k
                scaled.append(lm)
            out.append(scaled)
        return out


# -- metrics ---------------------------------------------------------------------------------------------------

def body_xy(lm: np.ndarray) -> np.ndarray:
    from posed.fitting import BODY_LANDMARKS

    return np.asarray(lm, dtype=np.float64)[list(BODY_LANDMARKS), :2]


def torso_px(lm: np.ndarray) -> float:
    """Mid-shoulder to mid-hip, pixels (BlazePose 11, 12 and 23, 24)."""
    lm = np.asarray(lm, dtype=np.float64)
    return float(np.hypot(*((lm[11, :2] + lm[12, :2]) / 2 - (lm[23, :2] + lm[24, :2]) / 2)))


def box_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of the boxes around two sets of 2D points (NaN points left out; 0 when either has none)."""
    from posed.landmarks import box_iou as iou_of_boxes

    def box(p):
        p = p[np.isfinite(p).all(axis=1)]
        return np.concatenate([p.min(axis=0), p.max(axis=0)]) if len(p) else None
    ba, bb = box(a), box(b)
    return 0.0 if ba is None or bb is None else iou_of_boxes(ba, bb)


def main_person(people: list[np.ndarray]) -> np.ndarray | None:
    """The person with the longest torso in the image (the one in front), None when nobody."""
    return max(people, key=torso_px) if people else None


def match(reference: np.ndarray, people: list[np.ndarray]) -> np.ndarray | None:
    """The person of ``people`` whose body box overlaps the reference's most, if by IoU >= MATCH_IOU."""
    ref = body_xy(reference)
    best, best_iou = None, MATCH_IOU
    for p in people:
        iou = box_iou(ref, body_xy(p))
        if iou >= best_iou:
            best, best_iou = p, iou
    return best


def _pct(values: list[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)), 3) if values else None


def score(reference: list[np.ndarray | None], found: list[list[np.ndarray]], lumas: list[float]) -> dict:
    """One condition on one source against the original's main person per frame (see the module docstring)."""
    dev_px, dev_torso = [], []
    ref_frames = hits = 0
    for ref, people in zip(reference, found, strict=True):
        if ref is None:
            continue
        ref_frames += 1
        got = match(ref, people)
        if got is None:
            continue
        hits += 1
        d = np.linalg.norm(body_xy(got) - body_xy(ref), axis=1)
        d = d[np.isfinite(d)]
        dev_px += d.tolist()
        torso = torso_px(ref)
        if torso > 1.0:
            dev_torso += (d / torso).tolist()
    return {"reference_frames": ref_frames, "found": hits,
            "found_rate": round(hits / ref_frames, 4) if ref_frames else None,
            "dev_px_median": _pct(dev_px, 50), "dev_px_p90": _pct(dev_px, 90),
            "dev_torso_median": _pct(dev_torso, 50), "dev_torso_p90": _pct(dev_torso, 90),
            "mean_luma_median": round(float(np.median(lumas)), 2)}


def thresholds(rows: list[dict], levels: tuple[float, ...] = (0.95, 0.80)) -> dict:
    """From the ``colour f=1/N`` rows of one source: per level (a found rate), read from the dark end, the
    brightest light at which the rate is below the level with every darker light below it too (``lost_at``: its
    fraction, median mean luma and rate; None when the darkest light still holds), and the light just brighter
    (``held_to``; None when even the brightest is lost): the switch belongs between the two lumas. A brighter
    light whose rate dips below the level with brighter and darker lights above it (a frame or two lost to
    the noise, not to the darkness) is listed in ``dips``."""
    dims = sorted((r for r in rows if r["kind"] == "dim" and not r.get("gain")),
                  key=lambda r: r["value"])     # darkest first
    out = {}
    if not dims:                # no colour f=1/N row without the gain (a run of some conditions only)
        return out
    for level in levels:
        def ok(r, level=level):
            return r["found_rate"] is not None and r["found_rate"] >= level
        lost_i = None
        for i, r in enumerate(dims):
            if ok(r):
                break
            lost_i = i
        held = dims[0] if lost_i is None else (dims[lost_i + 1] if lost_i + 1 < len(dims) else None)
        lost = None if lost_i is None else dims[lost_i]
        start = 0 if lost_i is None else lost_i + 1
        out[f"{round(level * 100)}%"] = {
            "held_to": None if held is None else {"f": held["value"], "mean_luma": held["mean_luma_median"]},
            "lost_at": None if lost is None else {"f": lost["value"], "mean_luma": lost["mean_luma_median"],
                                                  "found_rate": lost["found_rate"]},
            "dips": [{"f": r["value"], "mean_luma": r["mean_luma_median"], "found_rate": r["found_rate"]}
                     for r in dims[start:] if not ok(r)]}
    return out


def run_bench(shared: Path, config, *, quick: int | None = None, seed: int = SEED,
              conds: list[Condition] | None = None, sources: str = "dev", only: set[str] | None = None,
              progress=lambda m: None) -> dict:
    """Every source under every condition (module docstring); one JSON-able dict. ``sources``: ``dev`` (the
    sources the thresholds were read on) or ``untouched`` (:data:`UNTOUCHED`, default conditions
    :func:`untouched_conditions`). ``only``: the names of the conditions to run (the original always runs);
    each still draws the frames it draws in the whole list."""
    conds = conds or (untouched_conditions() if sources == "untouched" else conditions())
    names = [c.name for c in conds]
    t0 = time.monotonic()
    stage = Stage(config)
    groups: dict[str, list[Clip]] = {}
    for clip in clips(shared, config.pipeline.target_fps, quick, sources):
        groups.setdefault(clip.source, []).append(clip)
    report_sources = []
    for s_idx, (source, group) in enumerate(groups.items()):
        reference: list[np.ndarray | None] = []
        per_cond: dict[str, dict] = {}
        for c_idx, cond in enumerate(conds):
            if only is not None and cond.kind != "colour" and cond.name not in only:
                continue
            found, lumas, gains, after = [], [], [], []
            # a +gain condition draws the same frames (seed) as the condition without it
            seed_idx = names.index(cond.base) if cond.gain and cond.base in names else c_idx
            for k_idx, clip in enumerate(group):
                apply = transform(cond, hash_seed(seed, s_idx, seed_idx, k_idx), clip.frames[0][1].shape[:2])
                images = []
                for index, image in clip.frames:
                    out, y = apply(image)
                    images.append((index, out))
                    lumas.append(y)
                found += stage.run(iter(images), clip.fps, cond.gain, gains, after)
            if cond.kind == "colour":
                reference = [main_person(p) for p in found]
            per_cond[cond.name] = {"condition": cond.name, "kind": cond.kind, "value": cond.value,
                                   **score(reference, found, lumas)}
            if cond.gain:
                per_cond[cond.name].update(gain=cond.gain, gain_median=round(float(np.median(gains)), 3),
                                           gained_luma_median=round(float(np.median(after)), 2))
            progress(f"night: {source} {cond.name}: {per_cond[cond.name]['found']}/"
                     f"{per_cond[cond.name]['reference_frames']} found, luma {per_cond[cond.name]['mean_luma_median']}"
                     f" ({time.monotonic() - t0:.0f} s)")
        rows = list(per_cond.values())
        report_sources.append({"source": source, "clips": [c.name for c in group],
                               "frames": sum(len(c.frames) for c in group),
                               "image_size": list(group[0].frames[0][1].shape[1::-1]),
                               "rows": rows, "thresholds": thresholds(rows)})
    return {"benchmark": "night", "source_set": sources, "seed": seed, "match_iou": MATCH_IOU, "sensor": sensor_params(),
            "dots": {"count": ns.DOTS, "sigma_px_at_1280": ns.DOT_SIGMA_PX, "levels_x_mean_luma": list(DOT_LEVELS)},
            "landmarks_config": {"max_people": config.landmarks.max_people, "tracking": config.landmarks.tracking,
                                 "frame_max_pixels": config.pipeline.frame_max_pixels,
                                 "target_fps": config.pipeline.target_fps},
            "sources": report_sources, "wall_s": round(time.monotonic() - t0, 1)}


def hash_seed(*parts: int) -> int:
    """A seed from several integers, the same on every run."""
    return int(np.random.SeedSequence(list(parts)).generate_state(1)[0])


def sensor_params() -> dict:
    s = ns.OV2740
    return {"name": s.name, "full_well_e": s.full_well_e, "read_noise_e": s.read_noise_e,
            "max_gain": round(s.max_gain, 3), "adc_bits": s.adc_bits}


def fmt(v, spec: str = ".2f") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def table(report: dict) -> list[str]:
    """The report as text lines: one table, then the thresholds per source."""
    lines = [f"{'source':18} {'condition':26} {'luma':>6} {'found':>9} {'rate':>6} {'px med':>7} {'px p90':>7} "
             f"{'torso med':>9} {'torso p90':>9}  (+gain: median gain -> median luma the models saw)"]
    for s in report["sources"]:
        for r in s["rows"]:
            gain = (f"  x{r['gain_median']:.2f} -> {r['gained_luma_median']:.1f}" if r.get("gain") else "")
            lines.append(f"{s['source']:18} {r['condition']:26} {fmt(r['mean_luma_median'], '.1f'):>6} "
                         f"{r['found']:>4}/{r['reference_frames']:<4} {fmt(r['found_rate'], '.3f'):>6} "
                         f"{fmt(r['dev_px_median'], '.1f'):>7} {fmt(r['dev_px_p90'], '.1f'):>7} "
                         f"{fmt(r['dev_torso_median'], '.3f'):>9} {fmt(r['dev_torso_p90'], '.3f'):>9}{gain}")
    lines.append("")
    lines.append("colour in dim light, read from the dark end: lost at = the brightest light with it and every "
                 "darker one under the rate; held to = the light above it")
    for s in report["sources"]:
        cells = []
        for level, t in s["thresholds"].items():
            held = "never" if t["held_to"] is None else f"1/{round(1 / t['held_to']['f'])} luma {t['held_to']['mean_luma']:.1f}"
            lost = ("not lost" if t["lost_at"] is None else
                    f"1/{round(1 / t['lost_at']['f'])} luma {t['lost_at']['mean_luma']:.1f} "
                    f"rate {t['lost_at']['found_rate']}")
            dips = "".join(f" (dip at 1/{round(1 / d['f'])}: luma {d['mean_luma']:.1f} rate {d['found_rate']})"
                           for d in t["dips"])
            cells.append(f">= {level}: held to {held}, lost at {lost}{dips}")
        lines.append(f"{s['source']:18} " + "; ".join(cells))
    return lines
