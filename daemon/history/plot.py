"""Joint-angle trajectories drawn with OpenCV, laid out like the paper's Figures 12 and 16.

One panel per group of angles (x: seconds from the first sample, y: degrees); left side solid, right side
dashed; fall events as labelled vertical lines. Gaps longer than ``gap_s`` break the lines.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

PANELS: dict[str, tuple[str, ...]] = {
    "torso": ("theta_tr", "phi_tr", "psi_tr"),
    "sagittal": ("theta_sh_l", "theta_sh_r", "theta_el_l", "theta_el_r", "theta_hp_l", "theta_hp_r",
                 "theta_kn_l", "theta_kn_r"),
    "body": ("theta_bd", "phi_bd", "psi_bd"),
}
# BGR colours per joint family
_COLOURS = {"sh": (40, 140, 40), "el": (200, 120, 0), "hp": (0, 0, 210), "kn": (160, 0, 160),
            "tr": (0, 0, 210), "hd": (90, 90, 90), "an": (0, 140, 200), "bd": (200, 120, 0)}
_AXIS_COLOURS = {"theta": (0, 0, 210), "phi": (200, 120, 0), "psi": (40, 140, 40)}


@dataclass(frozen=True)
class Mark:
    """A vertical marker (a fall event) at unix time ``wall``."""

    wall: float
    label: str


def _colour(name: str, panel_names: Sequence[str]) -> tuple[int, int, int]:
    parts = name.split("_")
    families = {n.split("_")[1] for n in panel_names}
    if len(families) == 1:  # a panel of one joint: colour by axis (theta/phi/psi)
        return _AXIS_COLOURS.get(parts[0], (0, 0, 0))
    return _COLOURS.get(parts[1], (0, 0, 0))


def _nice_step(span: float, target: int) -> float:
    raw = max(span, 1e-9) / target
    mag = 10 ** np.floor(np.log10(raw))
    for m in (1, 2, 5, 10):
        if m * mag >= raw:
            return float(m * mag)
    return float(10 * mag)


def _dashed(img, p0, p1, colour, thickness, dash=8):
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.hypot(*(p1 - p0)))
    if length < 1:
        return
    n = max(1, int(length // dash))
    for i in range(0, n, 2):
        a = p0 + (p1 - p0) * (i / n)
        b = p0 + (p1 - p0) * (min(i + 1, n) / n)
        cv2.line(img, tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b), colour, thickness,
                 cv2.LINE_AA)


def draw_history(wall: np.ndarray, angles: dict[str, np.ndarray], panels: Sequence[tuple[str, Sequence[str]]],
                 marks: Sequence[Mark] = (), title: str = "", width: int = 1200, panel_height: int = 320,
                 gap_s: float | None = None) -> np.ndarray:
    """Render the panels to a BGR image. ``wall``: unix seconds (N,); ``angles[name]``: degrees (N,), NaN
    where unknown; ``panels``: (panel title, angle names)."""
    wall = np.asarray(wall, float)
    margin_l, margin_r, margin_t, margin_b = 70, 170, 40, 45
    height = margin_t // 2 + len(panels) * panel_height
    img = np.full((height + 10, width, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    if title:
        cv2.putText(img, title, (margin_l, 22), font, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    t0 = float(wall[0]) if wall.size else 0.0
    t = wall - t0
    t_end = float(t[-1]) if t.size else 1.0
    t_span = max(t_end, 1e-3)
    if gap_s is None:
        gap_s = 3.0 * float(np.median(np.diff(t))) if t.size > 2 else np.inf
    for k, (panel_title, names) in enumerate(panels):
        top = margin_t // 2 + k * panel_height + margin_t
        bottom = margin_t // 2 + (k + 1) * panel_height - margin_b
        left, right = margin_l, width - margin_r
        series = [(n, np.asarray(angles.get(n, np.full(t.shape, np.nan)), float)) for n in names]
        finite = np.concatenate([v[np.isfinite(v)] for _, v in series] + [np.zeros(0)])
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (-10.0, 10.0)
        if hi - lo < 10:
            mid = (hi + lo) / 2
            lo, hi = mid - 5, mid + 5
        pad = 0.05 * (hi - lo)
        lo, hi = lo - pad, hi + pad

        def px(tt, yy, lo=lo, hi=hi, left=left, right=right, top=top, bottom=bottom):
            return (left + (tt / t_span) * (right - left), bottom - (yy - lo) / (hi - lo) * (bottom - top))

        cv2.rectangle(img, (left, top), (right, bottom), (0, 0, 0), 1)
        ystep = _nice_step(hi - lo, 6)
        for yv in np.arange(np.ceil(lo / ystep) * ystep, hi, ystep):
            _, y = px(0, yv)
            cv2.line(img, (left, int(y)), (right, int(y)), (225, 225, 225), 1)
            cv2.putText(img, f"{round(float(yv), 6) + 0.0:g}", (left - 45, int(y) + 4), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        xstep = _nice_step(t_span, 10)
        for xv in np.arange(0, t_span + 1e-9, xstep):
            x, _ = px(xv, lo)
            cv2.line(img, (int(x), top), (int(x), bottom), (235, 235, 235), 1)
            cv2.putText(img, f"{xv:g}", (int(x) - 10, bottom + 16), font, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(img, "time (s)", ((left + right) // 2 - 25, bottom + 34), font, 0.45, (0, 0, 0), 1,
                    cv2.LINE_AA)
        cv2.putText(img, f"{panel_title} (deg)", (left, top - 8), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        for mark in marks:
            mt = mark.wall - t0
            if 0 <= mt <= t_span:
                x, _ = px(mt, lo)
                cv2.line(img, (int(x), top), (int(x), bottom), (0, 0, 255), 1)
                cv2.putText(img, mark.label, (int(x) + 3, top + 14), font, 0.4, (0, 0, 255), 1, cv2.LINE_AA)
        for i, (name, values) in enumerate(series):
            colour = _colour(name, names)
            dashed = name.endswith("_r")
            for j in range(1, t.size):
                if not (np.isfinite(values[j - 1]) and np.isfinite(values[j])) or t[j] - t[j - 1] > gap_s:
                    continue
                p0, p1 = px(t[j - 1], values[j - 1]), px(t[j], values[j])
                if dashed:
                    _dashed(img, p0, p1, colour, 2, dash=4)
                else:
                    cv2.line(img, (int(p0[0]), int(p0[1])), (int(p1[0]), int(p1[1])), colour, 2, cv2.LINE_AA)
            ly = top + 16 + 18 * i
            lx = right + 12
            if dashed:
                _dashed(img, (lx, ly - 4), (lx + 30, ly - 4), colour, 2, dash=4)
            else:
                cv2.line(img, (lx, ly - 4), (lx + 30, ly - 4), colour, 2, cv2.LINE_AA)
            cv2.putText(img, name, (lx + 36, ly), font, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    return img
