"""``posed fit`` of a recording that followed several people: a line per person per frame, each with
``person``, each person fitted by a fitter of their own exactly as if they had been alone (before, only the
frame's own person was fitted, and video mode carried one body's state into another's); ``posed plot fit``
then plots one person, never a curve jumping between bodies. Two real UR Fall recordings stand for two people
in one view."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

from posed.landmarks import LandmarkFrame, PersonLandmarks, read_recording, write_recording

ROOT = Path(__file__).resolve().parents[2]
N = 60
TIMING = ("fit_ms", "udeas_ms", "person")


def posed(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)


def _recordings(tmp_path: Path, shared_data: Path):
    ha, fa, _ = read_recording(shared_data / "falls/urfd_dev/urfd_00_fall.landmarks.jsonl")
    _, fb, _ = read_recording(shared_data / "falls/urfd_dev/urfd_18_adl.landmarks.jsonl")
    fa, fb = fa[:N], fb[:N]
    # the second person on the first one's clock (the same seq and t), alone and together
    fb = [LandmarkFrame(a.seq, a.t, b.landmarks, world=b.world) for a, b in zip(fa, fb, strict=True)]
    both = []
    for a, b in zip(fa, fb, strict=True):
        people = tuple(PersonLandmarks(i, f.landmarks, f.world, None) for i, f in ((4, a), (9, b))
                       if f.landmarks is not None)
        both.append(replace(a, people=people or None))
        assert both[-1].own_person() == (4 if a.landmarks is not None else None)   # the frame's own person
    assert fa[0].own_person() is None                                               # no people: nobody's
    paths = {}
    for name, frames in (("a", fa), ("b", fb), ("both", both)):
        paths[name] = tmp_path / f"{name}.landmarks.jsonl"
        write_recording(paths[name], ha, frames)
    return paths


def _fit(rec: Path, out: Path) -> list[dict]:
    r = posed("fit", str(rec), "-o", str(out))
    assert r.returncode == 0, r.stderr
    return [json.loads(line) for line in out.read_text().splitlines()]


def _strip(obj: dict) -> dict:
    return {k: v for k, v in obj.items() if k not in TIMING}


def test_each_person_is_fitted_as_if_alone(tmp_path, shared_data):
    paths = _recordings(tmp_path, shared_data)
    alone = {4: _fit(paths["a"], tmp_path / "a.jsonl"), 9: _fit(paths["b"], tmp_path / "b.jsonl")}
    assert all("person" not in o for lines in alone.values() for o in lines)   # one person: as before
    both = _fit(paths["both"], tmp_path / "both.jsonl")
    by_seq: dict[int, list[dict]] = {}
    for o in both:
        by_seq.setdefault(o["seq"], []).append(o)
    compared = 0
    for pid, lines in alone.items():
        for ref in lines:
            mine = [o for o in by_seq.get(ref["seq"], []) if o.get("person") == pid]
            if not ref.get("ok") and not mine:
                continue                      # no person in that frame of that clip: no line for them
            assert len(mine) == 1, (pid, ref["seq"], by_seq.get(ref["seq"]))
            assert _strip(mine[0]) == _strip(ref), (pid, ref["seq"])
            compared += 1
    assert compared >= 2 * N - 10, compared
    for seq, lines in by_seq.items():
        if len(lines) == 2:
            assert [o["person"] for o in lines] == [4, 9], seq     # the frame's own person first


def test_plot_fit_plots_one_person(tmp_path, shared_data):
    paths = _recordings(tmp_path, shared_data)
    _fit(paths["both"], tmp_path / "both.jsonl")
    r = posed("plot", "fit", str(tmp_path / "both.jsonl"), "-o", str(tmp_path / "p.png"))
    assert r.returncode == 0, r.stderr
    assert "holds 2 people; plotting person" in r.stderr and "--person ID" in r.stderr, r.stderr
    r = posed("plot", "fit", str(tmp_path / "both.jsonl"), "--person", "9", "-o", str(tmp_path / "p9.png"))
    assert r.returncode == 0 and (tmp_path / "p9.png").stat().st_size > 10_000, r.stderr
    r = posed("plot", "fit", str(tmp_path / "both.jsonl"), "--person", "5", "-o", str(tmp_path / "p5.png"))
    assert r.returncode == 2 and "no such person" in r.stderr and "4 (" in r.stderr and "9 (" in r.stderr


def test_render_takes_each_persons_fit_from_the_file(tmp_path, shared_data):
    """posed render REC --fit FIT: every person drawn with their own fitted skeleton (before, only the frame's
    own person had one: the fit file was read by seq, one line per frame)."""
    import argparse

    from posed.commands.render import _from_recording
    from posed.daemon.config import load_config

    paths = _recordings(tmp_path, shared_data)
    _fit(paths["both"], tmp_path / "both.jsonl")
    args = argparse.Namespace(input=str(paths["both"]), fit=str(tmp_path / "both.jsonl"), hfov=None)
    _, _, _, items, problems = _from_recording(args, load_config(None))
    assert problems == 0
    two = [it for it in items if it[4]]
    assert len(two) >= N - 5
    for seq, _t, _lm, own, others in two:
        assert own is not None and own.extra.get("person") == 4, seq
        (pid, _marks, fit), = others
        assert pid == 9 and fit is not None and fit.extra.get("person") == 9 and fit.seq == seq
