"""fitting.proportions against a plain reference learner (the straightforward formulas, every estimate
computed from scratch): the same LimbScale, JSON and lengths to the last bit on random sample streams, the
learner's own lengths fed back as the fitter does, windows overflowing HISTORY."""

from __future__ import annotations

import json
import math
from dataclasses import fields

import numpy as np
import pytest

from posed.fitting import proportions as PR
from posed.fitting.body import BodyDimensions

_FIELDS = tuple(f.name for f in fields(BodyDimensions))


class _ReferenceLearner:
    """ProportionLearner as the formulas read: the windows as plain lists, sorted again for each estimate."""

    def __init__(self, base: BodyDimensions) -> None:
        self.base = base
        self.rows: dict[str, list[list[float]]] = {name: [] for name, _, _ in PR.GROUPS}
        self.added = dict.fromkeys(self.rows, 0)
        self.scale = PR.LimbScale()

    def add(self, group: str, row: list[float]) -> None:
        if all(math.isfinite(v) and v > 0 for v in row):
            self.rows[group] = (self.rows[group] + [row])[-PR.HISTORY:]
            self.added[group] += 1

    def observe(self, obs, w, k, dims: BodyDimensions) -> None:
        got = PR.samples(obs, w, k, dims)
        if not got:
            return
        size = dims.body_height_m / self.base.body_height_m
        rel = {f: getattr(dims, f) / getattr(self.base, f) / size for f in (*PR.LENGTH_FIELDS, "shoulder_half_m")}
        for name, ratios in got:
            fs = next(fs for g, fs, _ in PR.GROUPS if g == name)
            divisor = rel["shoulder_half_m"] if name == "hip" else 1.0
            self.add(name, [r * rel[f] / divisor for r, f in zip(ratios, fs, strict=True)])
        self.scale = self.estimate()

    def estimate(self) -> PR.LimbScale:
        raw = dict.fromkeys(PR.LENGTH_FIELDS, 1.0)
        for name, fs, pct in PR.GROUPS:
            n = len(self.rows[name])
            if n < PR.MIN_SAMPLES:
                continue
            for c, f in enumerate(fs):
                v = sorted(row[c] for row in self.rows[name])[int(pct / 100.0 * (n - 1))]
                raw[f] = min(max(1.0 + (v - 1.0) * n / (n + PR.PRIOR_SAMPLES), PR.BOUNDS[0]), PR.BOUNDS[1])
        raw = {f: v for f, v in raw.items() if abs(v - 1.0) >= PR.DEAD_ZONE}
        old = self.scale
        if set(raw) == set(old.ratio) and all(abs(raw[f] - old.ratio[f]) < PR.RESOLUTION for f in raw):
            return PR.LimbScale(old.ratio, old.size, dict(self.added))   # moved less than the resolution: kept
        height = sum(getattr(self.base, f) for f in PR.HEIGHT_FIELDS)
        size = height / sum(getattr(self.base, f) * raw.get(f, 1.0) for f in PR.HEIGHT_FIELDS)
        return PR.LimbScale(raw, size, dict(self.added))

    def dims(self) -> BodyDimensions:
        return BodyDimensions(*[getattr(self.base, f) * self.scale.of(f) for f in _FIELDS])

    def to_json(self) -> dict:
        s = self.scale
        return {**{f.removesuffix("_m"): round(s.of(f), 3) for f in PR.LENGTH_FIELDS},
                "size": round(s.size, 3), "samples": dict(s.samples)}


def _bits(v) -> str:
    return np.float64(v).tobytes().hex()


def _assert_same(learner: PR.ProportionLearner, ref: _ReferenceLearner) -> None:
    got, want = learner.scale, ref.scale
    assert list(got.ratio) == list(want.ratio)                       # fields and their order
    assert [_bits(v) for v in got.ratio.values()] == [_bits(v) for v in want.ratio.values()]
    assert _bits(got.size) == _bits(want.size) and got.samples == want.samples
    assert json.dumps(got.to_json()) == json.dumps(ref.to_json())
    d, r = learner.dims(), ref.dims()
    assert [_bits(getattr(d, f)) for f in _FIELDS] == [_bits(getattr(r, f)) for f in _FIELDS]


def _standing(rng: np.random.Generator) -> np.ndarray:
    """12 body landmarks (normalized units, y down) of a person standing with hanging arms, jittered so that
    some segments lean beyond the tilt limits and some pairs mismatch."""
    x = np.array([-0.12, 0.12, -0.15, 0.15, -0.16, 0.16, -0.08, 0.08, -0.09, 0.09, -0.09, 0.09])
    y = np.array([-0.30, -0.30, -0.13, -0.13, 0.02, 0.02, 0.0, 0.0, 0.25, 0.25, 0.50, 0.50])
    return np.column_stack((x, y)) + rng.normal(scale=rng.choice([0.005, 0.03, 0.08]), size=(12, 2))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_observe_matches_the_reference_learner(seed):
    """Random frames observed with the learner's own lengths (as the fitter does) or other bodies; windows
    past HISTORY; forget in between."""
    rng = np.random.default_rng(seed)
    base = BodyDimensions.from_height(float(rng.uniform(1.5, 1.9)))
    learner, ref = PR.ProportionLearner(base), _ReferenceLearner(base)
    for i in range(PR.HISTORY + 250):
        if i == 300 and seed == 2:
            learner.forget()
            ref = _ReferenceLearner(base)
        obs = _standing(rng)
        w = (rng.random(12) > 0.05).astype(float) if i % 13 else np.zeros(12)   # no samples: the scale is kept
        k = (rng.uniform(0.9, 1.2, size=12) * (1.0 + 0.25 * seed) / base.body_height_m  # ratios around 1 (seed 1)
             * (rng.uniform(0.6, 1.4) if i % 7 == 0 else 1.0))
        dims = learner.dims() if i % 11 else BodyDimensions.from_height(float(rng.uniform(1.5, 1.9)))
        learner.observe(obs, w, k, dims)
        ref.observe(obs, w, k, dims)
        _assert_same(learner, ref)


def test_added_samples_match_the_reference_learner():
    """Rows straight into the windows: around the dead zone and the bounds, non-finite and non-positive ones
    left out, HISTORY overflow, duplicates."""
    rng = np.random.default_rng(7)
    base = BodyDimensions.from_height(1.7)
    learner, ref = PR.ProportionLearner(base), _ReferenceLearner(base)
    bad = (math.nan, math.inf, -math.inf, 0.0, -0.5)
    for i in range(2 * PR.HISTORY):
        for name, fs, _ in PR.GROUPS:
            if rng.random() < 0.3:
                continue
            row = [float(rng.choice([rng.uniform(0.5, 1.5), 1.0 + PR.DEAD_ZONE * rng.choice([-1, 1]), 0.97, 1.0]))
                   for _ in fs]
            if rng.random() < 0.05:
                row[int(rng.integers(len(row)))] = float(rng.choice(bad))
            learner.add(name, row)
            ref.add(name, row)
        if i % 3 == 0:   # the estimate is made by observe: here after some rows of every group
            learner._scale = learner._estimate()
            ref.scale = ref.estimate()
            _assert_same(learner, ref)


def test_limb_scale_json_is_a_new_dict_each_call():
    """The rounding is kept per LimbScale: what a caller does to a returned dict does not reach the next."""
    scale = PR.LimbScale({"thigh_m": 1.08, "upper_arm_m": 0.85}, 0.97, {"arm": 12, "leg": 30})
    a = scale.to_json()
    want = json.dumps(a)
    assert want == json.dumps({"upper_arm": round(0.97 * 0.85, 3), "forearm": 0.97, "thigh": round(0.97 * 1.08, 3),
                               "shank": 0.97, "trunk": 0.97, "hip_half": 0.97, "size": 0.97,
                               "samples": {"arm": 12, "leg": 30}})
    a["size"] = 5.0
    a["thigh"] = 2.0
    a["samples"]["arm"] = 0
    b = scale.to_json()
    assert b is not a and json.dumps(b) == want and scale.samples == {"arm": 12, "leg": 30}
    other = PR.LimbScale({"thigh_m": 1.2}, 0.9, {"leg": 31})   # another scale: its own values
    assert other.to_json()["thigh"] == round(0.9 * 1.2, 3) and scale.to_json()["thigh"] == round(0.97 * 1.08, 3)
