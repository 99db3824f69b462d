"""The person's own proportions (limb lengths, trunk, hip width), learned in video mode from the frames
themselves (no calibration file).

Why: link lengths from the body height alone (fitting.body, Drillis-Contini ratios) are off by 10-20 % for
many people and for the joint centres a landmark extractor reports (a subject of the CMU motion capture: upper
arm and forearm 14-16 % shorter than the ratios give, thigh 8 % longer). A limb modelled too long cannot lie in
the image plane: the fit tilts it towards or away from the camera to shorten it, with a random depth sign. On
the out-of-domain benchmark that mismatch is the largest error source (docs/bench/fit.md, "Reading").

How: projection only shortens. For a segment of model length ``L`` whose two landmarks are ``l`` apart in the
image, ``r = l / (L k)`` is the fraction of its model length the image shows, with ``k`` the image scale at
the segment's fitted depth (normalized image units per metre: ``g / H`` orthographic, ``fn_y / Z`` pinhole).
A segment in the image plane shows ``r = L_true / L``; one tilted out of it, less. Evidence is taken only from
frames where a limb hangs or stands (both of its segments within ``MAX_IMAGE_TILT_DEG`` of the image's
vertical, pointing down, the trunk upright): for an arm hanging and a leg standing under gravity that is near
the image plane of a roughly level camera. The two segments of a limb must show similar fractions (within
``MAX_PAIR_MISMATCH``): a thigh pointing at the camera (sitting, facing it) projects short and vertical but its
shank does not, and that frame says nothing about the thigh's length. The trunk is sampled likewise, the hip
width as a ratio to the shoulder width (see ``samples``). The estimate is a percentile (GROUPS) of
``r`` over the last ``HISTORY`` such samples (left and right pooled, one person), shrunk towards the model by
``PRIOR_SAMPLES`` pseudo-samples, within ``BOUNDS``, and not applied within ``DEAD_ZONE`` of 1 (people differ
by a few per cent from the ratios; a change that small is within the estimate's own scatter and would only
unsettle the fit). The image shows proportions, not size: the whole body is then scaled so that thigh, shank
and trunk add up to the configured ones (the height the user configured keeps the person's distance right).

With a depth camera the lengths are measured directly (``pts`` of :meth:`ProportionLearner.observe`): each
landmark the fit sees with a consistent depth is placed in 3D (its pixel's ray at the measured depth plus the
surface offset), and every frame gives each segment whose two ends are placed a sample of its 3D length,
whatever the pose. Depth noise only lengthens a segment on average (by about ``sigma^2 / L``: 4 mm, 2 %, for a
forearm at 3 m), and that is taken off each sample's square; no percentile is needed: the median is taken. A
group with at least MIN_DEPTH_SAMPLES such samples is learned from them instead of from the image. These
samples measure the length whatever the pose, so their scatter says how far to believe them: the median is
shrunk towards the model as a normal prior of spread ``PRIOR_SD`` shrinks it (``shrink``), not by a fixed
count of pseudo-samples (the image samples keep that: theirs is an upper envelope over poses, and a few
frames of one pose agree with each other without measuring the length).

**With BlazePose's world landmarks** (issue 38: they are metric; ``world`` of :meth:`ProportionLearner.observe`)
the lengths are measured the same way, from the world landmarks' 3D joint positions on every frame whatever the
pose: the median, shrunk by its scatter as the depth camera's samples are. They are the landmark model's own
joint centres, the very points the 2D landmarks mark, so the lengths they give are the ones the 2D landmarks
show (a motion-capture or another model's skeleton differs: a real video's upper arm 0.24 m in BlazePose's
world landmarks against 0.28 m between another model's triangulated joints). Their metres assume an average
body; only their ratios matter here: they teach the limbs and the trunk (``WORLD_GROUPS``), the three lengths
stacked in the height among them, so that their scale cancels when the whole body is scaled to the configured
height (below). Not the hip width: the image measures it as a ratio to the shoulders' (no scale), while
BlazePose's world hips spread with the pose (the real squat video: 1.23-1.33 of the model's hip width over the
squats, against 1.06-1.14 from the image's standing frames). Their errors are shared along a limb rather than
independent at each end, so nothing is taken off for noise. A depth camera, when it has enough samples of a
group, is used instead. Otherwise the world landmarks' lengths are the group's until the image has MIN_SAMPLES
of its own, and then the prior the image's estimate is shrunk towards (PRIOR_SAMPLES pseudo-samples), in place
of the configured body: the image measures a limb only in the image plane, the world landmarks on every frame
but with an error of their own, and the image's measurement is the one the 2D fit must agree with. A person
seen before (``retain``) keeps what was learned of them as that prior.

What was learned outlives a while without anybody in view (``ProportionLearner.retain``): the samples start
over, shrunk towards the learned ratios instead of the configured ones, so a person coming back is fitted with
their own proportions at once and someone else's samples move them as they would move the configured ones;
``forget`` goes back to the configured body (another person for certain, another recording).

Units: lengths in metres; ratios unitless; image coordinates in the fit's normalized units (fitting.problem).
Plain Python and NumPy (no kernels); the caller (fitting.fitter) decides when to observe, apply, retain and
forget.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from statistics import NormalDist

import numpy as np

from posed.camera_model import Intrinsics
from posed.fitting.body import BodyDimensions
from posed.fitting.image2d import distance, down_tilt_deg

# limbs: (upper segment, lower segment), their length fields and the body-12 indices (fitting.kinematics
# BODY_LANDMARKS order: shoulders 0/1, elbows 2/3, wrists 4/5, hips 6/7, knees 8/9, ankles 10/11) per side
LIMBS = (
    ("upper_arm_m", "forearm_m", ((0, 2, 4), (1, 3, 5))),
    ("thigh_m", "shank_m", ((6, 8, 10), (7, 9, 11))),
)
# what is learned: (name, length fields, percentile of the samples); the samples of each: see samples()
GROUPS = (
    ("arm", ("upper_arm_m", "forearm_m"), 75.0),
    ("leg", ("thigh_m", "shank_m"), 75.0),
    ("trunk", ("trunk_m",), 75.0),
    ("hip", ("hip_half_m",), 50.0),
)
LENGTH_FIELDS = tuple(f for _, fs, _ in GROUPS for f in fs)
HEIGHT_FIELDS = ("thigh_m", "shank_m", "trunk_m")   # stacked when standing: their sum is kept
MAX_IMAGE_TILT_DEG = 25.0   # a segment within this of the image's vertical (pointing down) counts
MAX_TRUNK_TILT_DEG = 30.0   # the trunk (mid-hip -> mid-shoulder) within this of the image's vertical (up)
MAX_PAIR_MISMATCH = 0.3     # |r_upper / r_lower - 1| above this: one of the two is foreshortened
MIN_FACING = 0.5            # hip width: the shoulders show at least this fraction of their width (not edge-on)
WORLD_GROUPS = ("arm", "leg", "trunk")   # the groups BlazePose's world landmarks teach (module docstring)
HISTORY = 600               # samples kept per group (newest win): 30 s of both sides at 10 fps
DEPTH_SAMPLE_RANGE = (0.5, 2.0)   # a 3D sample outside this ratio to the configured length is garbage (left out)
DEPTH_MIN_WEIGHT = 0.25     # a landmark's depth is used for lengths when its robust weight is at least this
                            # (fitting.depth_term: within one sigma of the fitted pose's depth; hidden: 0)
PRIOR_SAMPLES = 20          # the model's own lengths count as this many samples
MIN_SAMPLES = 10            # no estimate from fewer samples
MIN_DEPTH_SAMPLES = 5       # 3D samples (depth) that replace a group's image estimate
PRIOR_SD = 0.10             # the person's lengths around the configured ones (1 sd, ratio) for the 3D samples'
                            # shrinkage: a few per cent between people of one height, plus the landmark
                            # detector's joint centres against the model's (a CMU subject's arms: 14-16 % shorter)
BOUNDS = (0.7, 1.3)         # learned length / configured length
DEAD_ZONE = 0.03            # |ratio - 1| below this: keep the configured length
RESOLUTION = 0.005          # learned ratios that all move less than this keep their previous values: a new
                            # body costs a rebuild of the fit's problem, and so small a change is below the
                            # estimate's own scatter (3D samples move the median on most frames)
_FIELDS = tuple(f.name for f in fields(BodyDimensions))   # BodyDimensions' fields, in order
_IQR_SD = 2.0 * NormalDist().inv_cdf(0.75)   # a normal distribution's interquartile range in sd (1.349)
_JSON_KEYS = tuple((f, f.removesuffix("_m")) for f in LENGTH_FIELDS)   # (field, its LimbScale.to_json key)
_REL_FIELDS = (*LENGTH_FIELDS, "shoulder_half_m")   # the lengths the samples are relative to


@dataclass(frozen=True)
class LimbScale:
    """What was learned: each learned length field's ratio to the configured proportions (absent = 1.0), the
    size factor of the whole body (every length, the height included), the image samples per group and the 3D
    samples per group (depth, and world landmarks; groups without any left out)."""

    ratio: dict[str, float] = field(default_factory=dict)
    size: float = 1.0
    samples: dict[str, int] = field(default_factory=dict)
    depth_samples: dict[str, int] = field(default_factory=dict)   # 3D samples per group (from depth)
    world_samples: dict[str, int] = field(default_factory=dict)   # 3D samples per group (world landmarks)

    def of(self, name: str) -> float:
        """The factor on the configured length ``name`` (any BodyDimensions field)."""
        return self.size * self.ratio.get(name, 1.0)

    def to_json(self) -> dict:
        """Each length field's factor (``of``) under its name without ``_m``, the size and the samples per
        group; a new dict on every call (callers may change it), the rounding done once per LimbScale (the
        fitter reports the scale on every video frame, and a frame without samples keeps it)."""
        rounded = self.__dict__.get("_rounded")
        if rounded is None:
            rounded = {key: round(self.of(f), 3) for f, key in _JSON_KEYS}
            rounded["size"] = round(self.size, 3)
            object.__setattr__(self, "_rounded", rounded)   # a cache, not a field (the scale is frozen)
        out = dict(rounded)
        out["samples"] = dict(self.samples)
        if self.depth_samples:
            out["depth_samples"] = dict(self.depth_samples)
        if self.world_samples:
            out["world_samples"] = dict(self.world_samples)
        return out


def joint_points(xy_px: np.ndarray, depth_m: np.ndarray, use: np.ndarray, surface_m: np.ndarray,
                 camera: Intrinsics) -> np.ndarray:
    """The 12 body joint centres in the camera frame (12 x 3, metres) from their pixels ``xy_px`` (12 x 2) and
    measured surface depths ``depth_m`` (12, metres along the optical axis): the joint lies ``surface_m`` (12)
    behind the surface; NaN rows where ``use`` (12, bool) is False. ``camera``: the pinhole that saw them."""
    return camera.deproject(xy_px[:, 0], xy_px[:, 1], np.where(use, depth_m + surface_m, np.nan))


def samples(obs: np.ndarray, w: np.ndarray, k: np.ndarray, dims: BodyDimensions) -> list[tuple[str, tuple]]:
    """The usable samples of one frame: ``(group, ratios)`` with one ratio per length field of the group, each
    the shown fraction ``r`` of the length ``dims`` gives (see the module docstring).

    ``obs``: the 12 body landmarks, (12, 2), normalized image units; ``w``: their weights (0 = not used);
    ``k``: the image scale at each landmark's fitted depth, normalized units per metre (12,).

    Only frames with an upright trunk give samples. ``arm`` / ``leg``: a hanging arm or a standing leg (both
    segments pointing down within MAX_IMAGE_TILT_DEG of the image's vertical, showing similar fractions).
    ``trunk``: mid-hip to mid-shoulder. ``hip``: the ratio of the hip width to the shoulder width shown,
    relative to the model's: both are horizontal lines across the same body, so turning the body shortens them
    alike and the ratio does not depend on which way the person faces (unless edge-on, left out)."""
    out: list[tuple[str, tuple]] = []
    p, ok, k = obs.tolist(), (np.asarray(w) > 0).tolist(), np.asarray(k).tolist()   # plain floats: per-frame cost
    if not (ok[0] and ok[1] and ok[6] and ok[7]):
        return out
    mid_sh = (0.5 * (p[0][0] + p[1][0]), 0.5 * (p[0][1] + p[1][1]))
    mid_hp = (0.5 * (p[6][0] + p[7][0]), 0.5 * (p[6][1] + p[7][1]))
    if 180.0 - down_tilt_deg(mid_hp, mid_sh) > MAX_TRUNK_TILT_DEG:   # the trunk does not point up
        return out
    k_sh, k_hp = 0.5 * (k[0] + k[1]), 0.5 * (k[6] + k[7])
    out.append(("trunk", (distance(mid_sh, mid_hp) / (dims.trunk_m * 0.5 * (k_sh + k_hp)),)))
    sh_shown = distance(p[0], p[1]) / (2 * dims.shoulder_half_m * k_sh)
    if sh_shown > MIN_FACING:
        out.append(("hip", (distance(p[6], p[7]) / (2 * dims.hip_half_m * k_hp) / sh_shown,)))
    for name, (f_up, f_lo, sides) in zip(("arm", "leg"), LIMBS, strict=True):
        l_up, l_lo = getattr(dims, f_up), getattr(dims, f_lo)
        for a, b, c in sides:
            if not (ok[a] and ok[b] and ok[c]):
                continue
            if down_tilt_deg(p[a], p[b]) > MAX_IMAGE_TILT_DEG or down_tilt_deg(p[b], p[c]) > MAX_IMAGE_TILT_DEG:
                continue
            r_up = distance(p[a], p[b]) / (l_up * 0.5 * (k[a] + k[b]))
            r_lo = distance(p[b], p[c]) / (l_lo * 0.5 * (k[b] + k[c]))
            if not (r_up > 0 and r_lo > 0) or abs(r_up / r_lo - 1.0) > MAX_PAIR_MISMATCH:
                continue
            out.append((name, (r_up, r_lo)))
    return out


def percentile_variance(pct: float) -> float:
    """n times the variance of the ``pct`` percentile of n normal samples, over their variance
    (``p (1 - p) / phi(z_p)^2``: pi / 2 for the median, 1.86 for the 75th percentile)."""
    p = pct / 100.0
    nd = NormalDist()
    return p * (1.0 - p) / nd.pdf(nd.inv_cdf(p)) ** 2


def toward_prior(v: float, n: int, n0: float, prior: float = 1.0) -> float:
    """The ratio ``v`` learned from ``n`` samples, its departure from ``prior`` (1: the configured proportion;
    else what was learned before, see ProportionLearner.retain) weighted ``n / (n + n0)`` (the prior counting as
    ``n0`` samples), within BOUNDS."""
    return min(max(prior + (v - prior) * n / (n + n0), BOUNDS[0]), BOUNDS[1])


def shrink(v: float, n: int, spread: float, pct_var: float, prior: float = 1.0) -> float:
    """The ratio ``v`` (a percentile of ``n`` samples of scatter ``spread``, 1 sd) after a normal prior at
    ``prior`` (1: the configured proportion) of sd PRIOR_SD: ``v``'s own variance is ``pct_var spread^2 / n``
    (``percentile_variance``), so the posterior mean weighs ``v - prior`` by ``n / (n + n0)``,
    ``n0 = pct_var spread^2 / PRIOR_SD^2`` (``toward_prior``): samples that agree are believed at once,
    scattered ones after many. Within BOUNDS."""
    return toward_prior(v, n, pct_var * spread * spread / (PRIOR_SD * PRIOR_SD), prior)


class _Window:
    """The last HISTORY samples of one group (GROUPS), each column also kept sorted (its percentile in O(1)),
    and what they teach (``learned``, computed again only after a sample was added)."""

    def __init__(self, fields: tuple[str, ...], pct: float, scatter_prior: bool = False,
                 prior: dict[str, float] | None = None) -> None:
        """``scatter_prior``: 3D samples, learned from MIN_DEPTH_SAMPLES on and shrunk by their scatter
        (``shrink``); else image samples, from MIN_SAMPLES on and shrunk by PRIOR_SAMPLES. ``prior``: the
        ratios the samples are shrunk towards (absent fields: 1, the configured proportion), and what the
        window teaches before it has enough samples."""
        self.fields, self.pct = fields, pct
        self.prior = [(prior or {}).get(f, 1.0) for f in fields]
        self.pct_var = percentile_variance(pct) if scatter_prior else None
        self.min_samples = MIN_DEPTH_SAMPLES if scatter_prior else MIN_SAMPLES
        self.ring: deque[list[float]] = deque()   # in arrival order, newest last (at most HISTORY)
        self.sorted: list[list[float]] = [[] for _ in fields]
        self.added = 0                        # samples ever added
        self._learned: dict[str, float] | None = None   # None: to be computed again

    def add(self, row: list[float]) -> None:
        """Add ``row`` (one value per field)."""
        cols = self.sorted
        if len(self.ring) == HISTORY:         # the oldest sample leaves
            for i, v in enumerate(self.ring.popleft()):
                del cols[i][bisect.bisect_left(cols[i], v)]
        self.ring.append(row)
        for i, v in enumerate(row):
            bisect.insort(cols[i], v)
        self.added += 1
        self._learned = None

    def rank(self, pct: float) -> list[float]:
        """Each column's value of rank ``int(pct / 100 (n - 1))`` (0 = the smallest)."""
        i = int(pct / 100.0 * (len(self.ring) - 1))
        return [col[i] for col in self.sorted]

    def ready(self) -> bool:
        """Whether the window holds enough samples for an estimate (``min_samples``)."""
        return len(self.ring) >= self.min_samples

    def learned(self) -> dict[str, float]:
        """Each field's learned ratio to the configured proportions, outside DEAD_ZONE only: the group's
        percentile shrunk towards the prior (by PRIOR_SAMPLES, or by the samples' scatter from their
        interquartile range, see ``shrink``), within BOUNDS; below ``min_samples`` the prior itself."""
        if self._learned is None:
            n = len(self.ring)
            if not self.ready():
                self._learned = _outside_dead_zone(zip(self.fields, self.prior, strict=True))
            elif self.pct_var is None:
                self._learned = self._image_ratios(self.prior)
            else:
                cols = zip(self.fields, self.rank(self.pct), self.rank(25.0), self.rank(75.0), self.prior,
                           strict=True)
                self._learned = _outside_dead_zone(
                    (f, shrink(v, n, (q3 - q1) / _IQR_SD, self.pct_var, c)) for f, v, q1, q3, c in cols)
        return self._learned

    def learned_towards(self, prior: dict[str, float]) -> dict[str, float]:
        """As :meth:`learned` for image samples (``min_samples`` of them at least), shrunk towards ``prior``
        (ratios; absent fields: 1) instead of the window's own prior."""
        return self._image_ratios([prior.get(f, 1.0) for f in self.fields])

    def _image_ratios(self, priors: list[float]) -> dict[str, float]:
        """Each field's percentile shrunk towards its entry of ``priors`` by PRIOR_SAMPLES, outside DEAD_ZONE."""
        n = len(self.ring)
        return _outside_dead_zone((f, toward_prior(v, n, PRIOR_SAMPLES, c))
                                  for f, v, c in zip(self.fields, self.rank(self.pct), priors, strict=True))


def _outside_dead_zone(ratios: Iterable[tuple[str, float]]) -> dict[str, float]:
    """The (field, ratio) pairs of ``ratios`` farther than DEAD_ZONE from 1 (closer: the configured length)."""
    return {f: r for f, r in ratios if abs(r - 1.0) >= DEAD_ZONE}


class ProportionLearner:
    """Learns the person's proportions from video frames; ``dims()`` gives the lengths to fit with."""

    def __init__(self, base: BodyDimensions) -> None:
        self.base = base   # fixed for the learner's life: the caches below depend on it
        self._height_lengths = tuple(getattr(base, f) for f in HEIGHT_FIELDS)
        self._height = sum(self._height_lengths)   # the configured stack of HEIGHT_FIELDS, metres
        self._height_pairs = tuple(zip(HEIGHT_FIELDS, self._height_lengths, strict=True))   # (field, metres)
        self._base_pairs = tuple((name, getattr(base, name)) for name in _FIELDS)   # (field, metres)
        self._base_lengths = dict(self._base_pairs)
        self._rel_pairs = tuple((f, getattr(base, f)) for f in _REL_FIELDS)   # (field, metres)
        self._rel_dims: BodyDimensions | None = None   # the dims self._rel was computed for
        self._rel: dict[str, tuple[list[float], float]] = {}
        self.forget()

    def forget(self) -> None:
        """Start over from the configured proportions (another person, another recording)."""
        self._start({})
        self._scale = LimbScale()
        self._dims_key: tuple | None = None   # the (size, ratios) self._dims was built for
        self._dims = self.base

    def retain(self) -> None:
        """Start the samples over with what was learned as their prior (a while without anybody in view): the
        same person coming back is fitted with their own proportions at once, and someone else's samples move
        them as they would move the configured ones."""
        self._start(dict(self._scale.ratio))

    def _start(self, prior: dict[str, float]) -> None:
        """Empty sample windows shrinking towards ``prior`` (ratios to the configured proportions; absent: 1)."""
        self._retained = bool(prior)   # the samples start from what was learned of a person before (retain)
        # per group: the recent samples as multiples of the *configured* proportions
        self._win = {name: _Window(fs, pct, prior=prior) for name, fs, pct in GROUPS}   # GROUPS order
        self._win3 = {name: _Window(fs, 50.0, scatter_prior=True, prior=prior)   # 3D from depth (_add_3d)
                      for name, fs, _ in GROUPS}
        self._winw = {name: _Window(fs, 50.0, scatter_prior=True, prior=prior)   # 3D, world landmarks
                      for name, fs, _ in GROUPS if name in WORLD_GROUPS}

    @property
    def scale(self) -> LimbScale:
        return self._scale

    def observe(self, obs: np.ndarray, w: np.ndarray, k: np.ndarray, dims: BodyDimensions,
                pts: np.ndarray | None = None, depth_sd_m: float = 0.0, world: np.ndarray | None = None) -> None:
        """Add one fitted frame (see ``samples``; ``dims`` the lengths its fit used; ``pts`` its joint centres
        placed in 3D from depth with noise ``depth_sd_m`` along the optical axis; ``world`` the 12 body joints
        of BlazePose's world landmarks, metres, NaN rows where unknown; see :meth:`_add_3d`) and update the
        estimate."""
        got = samples(obs, w, k, dims)
        if got:
            rel = self._relative(dims)
            for name, ratios in got:
                factors, divisor = rel[name]
                self.add(name, [r * f / divisor for r, f in zip(ratios, factors, strict=True)])
        added = pts is not None and self._add_3d(self._win3, pts, depth_sd_m)
        added = (world is not None and self._add_3d(self._winw, world, 0.0)) or added
        if added or got:
            self._scale = self._estimate()

    def _add_3d(self, windows: dict[str, _Window], pts: np.ndarray, sd: float) -> bool:
        """Add one frame's 3D samples to ``windows`` (whether any was added): ``pts`` the 12 body joint centres
        (12 x 3, metres; NaN rows for landmarks without a usable 3D position, see :func:`joint_points`). Each
        sample is a segment's 3D length over the configured length (``arm``, ``leg``: both segments of a side;
        ``trunk``: mid-shoulder to mid-hip; ``hip``: the hip width). Noise of ``sd`` metres at each end, along
        one axis and independent, adds ``2 sd^2`` to a segment's expected squared length (``sd^2`` between two
        midpoints): taken off."""
        p = np.asarray(pts, dtype=np.float64).tolist()   # plain floats: per-frame cost
        mid_sh = [0.5 * (a + b) for a, b in zip(p[0], p[1], strict=True)]
        mid_hp = [0.5 * (a + b) for a, b in zip(p[6], p[7], strict=True)]
        base = self._base_lengths
        v2 = sd * sd

        def length(a: list[float], b: list[float], noise2: float) -> float:
            d2 = math.dist(a, b) ** 2   # NaN stays NaN
            return math.sqrt(max(d2 - noise2, 0.25 * d2))

        rows = [("trunk", [length(mid_sh, mid_hp, v2) / base["trunk_m"]]),
                ("hip", [length(p[6], p[7], 2 * v2) / (2.0 * base["hip_half_m"])])]
        for name, (f_up, f_lo, sides) in zip(("arm", "leg"), LIMBS, strict=True):
            for a, m, c in sides:
                rows.append((name, [length(p[a], p[m], 2 * v2) / base[f_up],
                                    length(p[m], p[c], 2 * v2) / base[f_lo]]))
        lo, hi = DEPTH_SAMPLE_RANGE
        added = False
        for name, row in rows:
            if name in windows and all(lo <= v <= hi for v in row):   # (False for NaN)
                windows[name].add(row)
                added = True
        return added

    def _relative(self, dims: BodyDimensions) -> dict[str, tuple[list[float], float]]:
        """Per group: (the proportion ``dims`` gives each of its lengths relative to the configured one, the
        divisor of its ratios); a sample's ratio times the one, divided by the other, is relative to the
        configured proportions. Cached for the last ``dims`` (a learned body is a new object whenever the
        estimate moved, most frames while learning)."""
        if dims is not self._rel_dims:
            size = dims.body_height_m / self.base.body_height_m   # the image shows no size: store proportions
            rel = {f: getattr(dims, f) / m / size for f, m in self._rel_pairs}
            # the hip sample is a ratio to the shoulders' shown width: relative to their proportion too
            self._rel = {name: ([rel[f] for f in fs], rel["shoulder_half_m"] if name == "hip" else 1.0)
                         for name, fs, _ in GROUPS}
            self._rel_dims = dims
        return self._rel

    def add(self, group: str, row: list[float]) -> None:
        """Add one sample of ``group`` (GROUPS), as multiples of the configured proportions; non-finite or
        non-positive rows are left out. ``observe`` calls it; the estimate is updated by the next observe."""
        if all(math.isfinite(v) and v > 0 for v in row):
            self._win[group].add(row)

    def _estimate(self) -> LimbScale:
        ratio: dict[str, float] = {}   # LENGTH_FIELDS order (GROUPS order, each group's fields in order)
        for name, win in self._win.items():
            depth, world = self._win3[name], self._winw.get(name)
            if depth.ready():                           # a depth camera's 3D lengths
                ratio.update(depth.learned())
            elif world is None or not world.ready():    # the image alone
                ratio.update(win.learned())
            elif not win.ready():                       # the world landmarks' 3D lengths until the image has some
                ratio.update(world.learned())
            elif self._retained:                        # the image, from what was learned of the person before
                ratio.update(win.learned())
            else:                                       # the image, from the world landmarks' lengths
                ratio.update(win.learned_towards(world.learned()))
        # the image shows proportions, not size: the whole body is scaled so that the legs and the trunk (stacked
        # when standing) add up to the configured ones, the person's height being what the user configured
        old = self._scale
        if ratio.keys() == old.ratio.keys() and all(abs(ratio[f] - v) < RESOLUTION for f, v in old.ratio.items()):
            ratio, size = old.ratio, old.size   # the same body: nothing to rebuild
        else:
            size = self._height / sum([m * ratio.get(f, 1.0) for f, m in self._height_pairs])
        return LimbScale(ratio, size, {name: win.added for name, win in self._win.items()},
                         {name: win.added for name, win in self._win3.items() if win.added},
                         {name: win.added for name, win in self._winw.items() if win.added})

    def dims(self) -> BodyDimensions:
        """The configured dimensions with the learned proportions (built again only when they change)."""
        scale = self._scale
        key = (scale.size, tuple(scale.ratio.items()))
        if key != self._dims_key:
            self._dims_key = key
            self._dims = BodyDimensions(*[v * scale.of(name) for name, v in self._base_pairs])
        return self._dims
