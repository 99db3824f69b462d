"""Two-person scenes composited from real single-person footage, for ``posed bench people`` (issue 36).

Person A is the woman of the real squat video (tfjs_pose_squats, 65 frames at 5 fps, 720x1280), whose BlazePose
full landmarks the tfjs-models project published (``pose_squats.full.json``: the truth A's errors are taken
against). Her room is the scene: each of her frames, scaled to the 1280x720 canvas's height, sits in its middle
(x 420..825), the canvas's sides continuing its edge columns (a plain wall and floor). Person B is the man of
pose2sim's real "balancing" video, camera 3 (``B_CAMERA``; 1088x1920, 60 fps; its first 65 frames), cut out of his video
and pasted in, scaled to the canvas height times his scenario's scale (smaller is farther away). His cut-out
(:func:`skeleton_masks`) is a GrabCut segmentation seeded by his own triangulated skeleton projected into the
view: the bones and the shoulder-hip quad are surely him, everything farther than ``BODY_REACH`` of his height
from them surely not, and in between the pixels that differ from the clip's median frame (the camera is still:
:func:`difference_masks`) start as probably him. The difference alone misses most of him (he is bare-armed in
grey-green shorts in a dim grey room: about half of his bones' pixels fall outside it, and what was pasted was
a scatter of skin patches, not a person who hides what is behind him). No learned segmentation, no image
leaves the machine. Person A keeps the difference mask: her white room makes it whole.

Scenarios (``SCENARIOS``): ``apart`` (B on the right, never touching A); ``cross_behind`` (B, smaller, walks
from the right edge past A to the left, drawn behind A: she hides him as they cross); ``cross_front`` (B, full
size, walks across in front of A: he hides her); ``cross_behind_ltr`` and ``cross_front_ltr`` (the same, left to
right). Each scene also exists with one person only (the same
placement; for A alone, her own frames; for B alone, her empty room, the median of her frames with the
canvas's sides): what the landmarker gives for each person alone is the reference of their two-person error.

Pixels in the canvas's frame; a scene is a list of BGR frames plus, per frame, A's and B's placement.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

SQUAT = Path("reference") / "tfjs_pose_squats"
BALANCING = Path("reference") / "pose2sim_demo" / "balancing"
B_CAMERA = "cam03"                       # the reported view; cam01, cam02 and cam04: development views
CANVAS = (1280, 720)                     # width, height
FRAMES = 65                              # the squat video's length
MASK_THRESHOLD = 40                      # summed |BGR - median| above which a pixel is the person's
BONE_WIDTH = 0.03                        # B's bones drawn this wide (fraction of his height): surely him
BODY_REACH = 0.08                        # farther than this (fraction of his height) from his bones: surely not
GRABCUT_SCALE = 0.35                     # GrabCut runs on his box scaled by this (0.2 s per frame, not 4.7)
GRABCUT_ITERATIONS = 4
GRABCUT_SEED = 0
# B's bones for his cut-out's seeds: names of pose2sim's .trc points
BONES = (("Nose", "Head"), ("Head", "Neck"), ("Neck", "RShoulder"), ("Neck", "LShoulder"),
         ("RShoulder", "RElbow"), ("RElbow", "RWrist"), ("LShoulder", "LElbow"), ("LElbow", "LWrist"),
         ("Neck", "RHip"), ("Neck", "LHip"), ("RHip", "RKnee"), ("RKnee", "RAnkle"), ("LHip", "LKnee"),
         ("LKnee", "LAnkle"), ("RAnkle", "RHeel"), ("RAnkle", "RBigToe"), ("LAnkle", "LHeel"), ("LAnkle", "LBigToe"))
TORSO = ("RShoulder", "LShoulder", "LHip", "RHip")


@dataclass(frozen=True)
class Placement:
    """Where a person's clip goes on the canvas: its left edge ``x`` and its ``scale`` of the canvas height
    (its bottom stays on the canvas's bottom)."""

    x: float
    scale: float = 1.0


@dataclass(frozen=True)
class Scenario:
    name: str
    a: tuple[Placement, ...]             # per frame
    b: tuple[Placement, ...]
    b_first: bool                        # B drawn before A (A in front)


def _linear(x0: float, x1: float, scale: float = 1.0) -> tuple[Placement, ...]:
    return tuple(Placement(x0 + (x1 - x0) * k / (FRAMES - 1), scale) for k in range(FRAMES))


A_X = 420                                # A's frame's left edge on the canvas

SCENARIOS = (
    Scenario("apart", (Placement(A_X),) * FRAMES, (Placement(930),) * FRAMES, False),
    Scenario("cross_behind", (Placement(A_X),) * FRAMES, _linear(1000, -150, 0.75), True),
    Scenario("cross_front", (Placement(A_X),) * FRAMES, _linear(1000, -150, 1.0), False),
    # the same crossings the other way (left to right): another instant of both people's motion at the
    # crossing, so that one crossing's luck is not all a view says
    Scenario("cross_behind_ltr", (Placement(A_X),) * FRAMES, _linear(-150, 1000, 0.75), True),
    Scenario("cross_front_ltr", (Placement(A_X),) * FRAMES, _linear(-150, 1000, 1.0), False),
)


def crossings(n: int, seed: int = 0) -> tuple[Scenario, ...]:
    """``n`` crossings drawn at random (``seed``), for a rate where one crossing's luck decides a fixed
    scenario: each is B walking across A, in front (scale 0.9-1.1) or behind (0.65-0.85), either way, from a
    start 950-1250 px to an end -350 to -100 px (mirrored for left to right), so that he passes her at a
    different instant of both people's motion. Named ``crossing_NN_front|behind_rtl|ltr``: in front and
    behind alternate, and so does the direction every two."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        front = i % 2 == 0
        rtl = (i // 2) % 2 == 0
        scale = float(rng.uniform(0.9, 1.1) if front else rng.uniform(0.65, 0.85))
        start, end = float(rng.uniform(950.0, 1250.0)), float(rng.uniform(-350.0, -100.0))
        if not rtl:
            start, end = end, start
        name = f"crossing_{i:02d}_{'front' if front else 'behind'}_{'rtl' if rtl else 'ltr'}"
        out.append(Scenario(name, (Placement(A_X),) * FRAMES, _linear(start, end, scale), not front))
    return tuple(out)


@dataclass
class Clip:
    """A person's frames, their foreground masks and (A only) the published landmarks, in the clip's pixels."""

    frames: list[np.ndarray]
    masks: list[np.ndarray]
    background: np.ndarray
    truth: list[np.ndarray] | None = None     # (33, 3) x, y, z per frame (A: her published landmarks)
    truth12: list[np.ndarray] | None = None   # (12, 2) per frame, BODY12 order (B: his triangulated joints projected)


def _read(path: Path, n: int) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    try:
        while len(out) < n:
            ok, image = cap.read()
            if not ok:
                break
            out.append(image)
    finally:
        cap.release()
    if not out:
        raise FileNotFoundError(f"{path}: no frame could be read (the shared data's real video)")
    return out


def difference_masks(frames: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """Per frame, the pixels that differ from the clip's median frame (the largest connected parts, closed and
    dilated), and that median frame (the background: the camera is still)."""
    background = np.median(np.stack(frames[:: max(1, len(frames) // 25)]), axis=0).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (9, 9))
    masks = []
    for f in frames:
        diff = np.abs(f.astype(np.int16) - background.astype(np.int16)).sum(axis=2) > MASK_THRESHOLD
        m = cv2.morphologyEx(diff.astype(np.uint8), cv2.MORPH_OPEN, kernel)
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, kernel, iterations=2)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(m)
        if n > 1:
            areas = stats[1:, cv2.CC_STAT_AREA]
            keep = 1 + np.flatnonzero(areas >= 0.2 * areas.max())
            m = np.isin(labels, keep).astype(np.uint8)
        masks.append(cv2.dilate(m, kernel) > 0)
    return masks, background


def skeleton_masks(frames: list[np.ndarray], difference: list[np.ndarray],
                   skeletons: list[dict[str, np.ndarray]]) -> list[np.ndarray]:
    """The person's pixels per frame: GrabCut seeded by their projected skeleton (``skeletons``: per frame, a
    .trc point's name -> its pixel), see the module doc; run on the skeleton's box scaled by ``GRABCUT_SCALE``
    and scaled back. OpenCV's RNG is seeded before each frame (``GRABCUT_SEED``): the same masks on every run."""
    out = []
    for frame, diff, joints in zip(frames, difference, skeletons, strict=True):
        h, w = frame.shape[:2]
        pts = np.array(list(joints.values()))
        height = max(float(np.ptp(pts[:, 1])), 1.0)
        sure = np.zeros((h, w), np.uint8)
        width = max(2, round(BONE_WIDTH * height))
        for p, q in BONES:
            cv2.line(sure, tuple(np.round(joints[p]).astype(int)), tuple(np.round(joints[q]).astype(int)), 1, width)
        cv2.fillConvexPoly(sure, np.round([joints[n] for n in TORSO]).astype(np.int32), 1)
        near = cv2.distanceTransform(1 - sure, cv2.DIST_L2, 5) <= BODY_REACH * height
        seeds = np.full((h, w), cv2.GC_BGD, np.uint8)
        seeds[near] = cv2.GC_PR_BGD
        seeds[near & diff] = cv2.GC_PR_FGD
        seeds[sure > 0] = cv2.GC_FGD
        ys, xs = np.nonzero(near)
        mask = np.zeros((h, w), bool)
        if xs.size:
            x0, x1, y0, y1 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
            small = cv2.resize(frame[y0:y1, x0:x1], None, fx=GRABCUT_SCALE, fy=GRABCUT_SCALE,
                               interpolation=cv2.INTER_AREA)
            sub = cv2.resize(seeds[y0:y1, x0:x1], (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST)
            models = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
            cv2.setRNGSeed(GRABCUT_SEED)         # its colour models start from k-means++ on OpenCV's own RNG
            cv2.grabCut(small, sub, None, *models, GRABCUT_ITERATIONS, cv2.GC_INIT_WITH_MASK)
            fg = ((sub == cv2.GC_FGD) | (sub == cv2.GC_PR_FGD)).astype(np.uint8)
            mask[y0:y1, x0:x1] = cv2.resize(fg, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR) > 0
        out.append(mask)
    return out


def load_clips(shared: Path, b_camera: str = B_CAMERA) -> tuple[Clip, Clip]:
    """Person A (the squat video, with its published landmarks) and person B (pose2sim's ``b_camera``)."""
    from posed.bench.balancing_video import TRC_NAMES
    from posed.bench.mocap_landmarks import BODY12

    a_frames = _read(shared / SQUAT / "pose_squats.mp4", FRAMES)
    truth = [np.asarray(f, dtype=np.float64) for f in json.loads((shared / SQUAT / "pose_squats.full.json").read_text())]
    a_masks, a_bg = difference_masks(a_frames)
    b_frames = _read(shared / BALANCING / f"{b_camera}.mp4", FRAMES)
    b_diff, b_bg = difference_masks(b_frames)
    skeletons = b_skeletons(shared, len(b_frames), b_camera)
    b_masks = skeleton_masks(b_frames, b_diff, skeletons)
    truth12 = [np.array([s[TRC_NAMES[n]] for n in BODY12]) for s in skeletons]
    return (Clip(a_frames, a_masks, a_bg, truth[: len(a_frames)]),
            Clip(b_frames, b_masks, b_bg, truth12=truth12))


def b_skeletons(shared: Path, n: int, b_camera: str) -> list[dict[str, np.ndarray]]:
    """B's points triangulated from pose2sim's four views (truth_3d.trc, the same frames as the video: the 12
    body joints his errors are taken against, and his head, neck, heels and toes), projected into ``b_camera``
    through its calibration, lens distortion included: per frame, name -> (2,) pixels."""
    from posed.bench import balancing_video as bv

    folder = shared / bv.DATA
    cam = bv.load_cameras(folder)[b_camera]
    names, world = bv.load_trc(folder)
    rvec, _ = cv2.Rodrigues(cam.rot)
    out = []
    for joints in world[:n]:
        px, _ = cv2.projectPoints(joints.reshape(-1, 1, 3), rvec, cam.t, cam.k, cam.dist)
        out.append(dict(zip(names, px.reshape(-1, 2), strict=True)))
    return out


def room(image: np.ndarray) -> tuple[np.ndarray, tuple[float, float, float]]:
    """``image`` (one of A's frames, or her empty room) scaled to the canvas height at x ``A_X``, the canvas's
    sides continuing its edge columns; and the mapping (s, dx, dy) from A's pixels to the canvas."""
    w, h = CANVAS
    s = h / image.shape[0]
    img = cv2.resize(image, (round(image.shape[1] * s), h), interpolation=cv2.INTER_AREA)
    right = w - A_X - img.shape[1]
    canvas = cv2.copyMakeBorder(img, 0, 0, A_X, right, cv2.BORDER_REPLICATE)
    return np.ascontiguousarray(canvas), (s, float(A_X), 0.0)


def empty_room(a: Clip) -> np.ndarray:
    """A's room without her: her median frame with the box around everywhere her mask ever reached (she
    squats in place, so parts of her never differ from the median) filled in from around it (cv2.inpaint)."""
    union = np.any(np.stack(a.masks), axis=0)
    ys, xs = np.nonzero(union)
    bg = a.background.copy()
    if xs.size:
        pad = 25
        hole = np.zeros(union.shape, np.uint8)
        hole[max(0, ys.min() - pad): ys.max() + 4 * pad, max(0, xs.min() - pad): xs.max() + pad] = 1   # the feet
        bg = cv2.inpaint(bg, hole, 9, cv2.INPAINT_TELEA)
    return bg


def _placed(clip: Clip, k: int, place: Placement) -> tuple[np.ndarray, np.ndarray, int, int, float]:
    """Frame ``k`` of ``clip`` and its mask scaled for ``place``: (image, mask, x0, y0, scale), where (x0, y0)
    is the scaled frame's top-left corner on the canvas (its bottom on the canvas's bottom)."""
    h = CANVAS[1]
    frame, mask = clip.frames[k % len(clip.frames)], clip.masks[k % len(clip.masks)]
    s = h * place.scale / frame.shape[0]
    size = (max(1, round(frame.shape[1] * s)), max(1, round(frame.shape[0] * s)))
    img = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
    m = cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    return img, m, round(place.x), h - size[1], s


def _window(x0: int, y0: int, shape: tuple[int, ...]) -> tuple[tuple[slice, slice], tuple[slice, slice]] | None:
    """Where an image of ``shape`` with its top-left corner at canvas (x0, y0) lands: (canvas rows, cols) and
    the same pixels' (rows, cols) in the image; None when it is off the canvas. A person taller than the canvas
    loses the top rows."""
    cx0, cx1 = max(0, x0), min(CANVAS[0], x0 + shape[1])
    cy0 = max(0, y0)
    if cx1 <= cx0:
        return None
    return (slice(cy0, y0 + shape[0]), slice(cx0, cx1)), (slice(cy0 - y0, None), slice(cx0 - x0, cx1 - x0))


def _paste(canvas: np.ndarray, clip: Clip, k: int, place: Placement) -> tuple[float, float, float]:
    """Paste frame ``k`` of ``clip``'s person at ``place``; returns (scale, dx, dy): clip pixels -> canvas."""
    img, m, x0, y0, s = _placed(clip, k, place)
    win = _window(x0, y0, img.shape)
    if win is not None:
        sub = m[win[1]]
        canvas[win[0]][sub] = img[win[1]][sub]
    return s, float(x0), float(y0)


def _mask_on_canvas(clip: Clip, k: int, place: Placement) -> np.ndarray:
    """The canvas pixels :func:`_paste` draws ``clip``'s person on, (height, width) bool."""
    _img, m, x0, y0, _ = _placed(clip, k, place)
    out = np.zeros(CANVAS[::-1], bool)
    win = _window(x0, y0, m.shape)
    if win is not None:
        out[win[0]] = m[win[1]]
    return out


def _a_mask_on_canvas(a: Clip, k: int) -> np.ndarray:
    return room((a.masks[k] * 255).astype(np.uint8))[0] > 127


def covers(a: Clip, b: Clip, scenario: Scenario) -> list[dict[str, np.ndarray]]:
    """Per frame of the two-person scene, the canvas pixels where each person is hidden by the other drawn over
    them: ``{"a": B's pixels when B is in front, "b": A's pixels when A is}``, (height, width) bool each. A
    landmark of a person that falls there has no pixel of that person to be found from."""
    none = np.zeros(CANVAS[::-1], bool)
    out = []
    for k in range(FRAMES):
        if scenario.b_first:
            out.append({"a": none, "b": _a_mask_on_canvas(a, k)})
        else:
            out.append({"a": _mask_on_canvas(b, k, scenario.b[k]), "b": none})
    return out


def compose(a: Clip, b: Clip, scenario: Scenario, who: str = "ab") -> tuple[list[np.ndarray], list[dict]]:
    """The scene's frames with ``who`` in view ("ab", "a" or "b") and, per frame, each person's mapping from
    their clip's pixels to the canvas ``{"a": (s, dx, dy), "b": ...}``."""
    empty = room(empty_room(a))[0]
    frames, maps = [], []
    for k in range(FRAMES):
        m = {}
        if "a" in who:
            canvas, m["a"] = room(a.frames[k])
        else:
            canvas = empty.copy()
        if "b" in who:
            if scenario.b_first and "a" in who:    # B behind A: only where A's mask leaves him visible
                behind = empty.copy()
                m["b"] = _paste(behind, b, k, scenario.b[k])
                a_mask = _a_mask_on_canvas(a, k)
                changed = np.any(behind != empty, axis=2) & ~a_mask
                canvas[changed] = behind[changed]
            else:
                m["b"] = _paste(canvas, b, k, scenario.b[k])
        frames.append(canvas)
        maps.append(m)
    return frames, maps


def truth_on_canvas(a: Clip, k: int, mapping: tuple[float, float, float]) -> np.ndarray:
    """A's published landmarks of frame ``k`` in canvas pixels, (33, 2)."""
    s, dx, dy = mapping
    return a.truth[k][:, :2] * s + np.array([dx, dy])


def truth12_on_canvas(b: Clip, k: int, mapping: tuple[float, float, float]) -> np.ndarray:
    """B's projected triangulated joints of frame ``k`` in canvas pixels, (12, 2), BODY12 order."""
    s, dx, dy = mapping
    return b.truth12[k % len(b.truth12)] * s + np.array([dx, dy])
