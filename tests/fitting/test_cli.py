"""``posed fit``, ``posed calibrate`` and the fit benchmark, run as a user would (real processes)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from posed.bench import simulate as S
from posed.landmarks import LandmarkFrame, RecordingHeader, write_recording

ROOT = Path(__file__).resolve().parents[2]


def posed(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "posed.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or ROOT, timeout=300)


def recording(path: Path, camera=None) -> Path:
    frames = S.render_sequence(S.sequence("stand_to_sit", 30.0), fps=10,
                               camera=S.LevelCamera(model="pinhole") if camera else None)
    out = [LandmarkFrame(i, t, lm) for i, (t, lm, _p) in enumerate(frames[:8])]
    out.append(LandmarkFrame(8, 0.8, None))                       # no person
    partial = frames[9][1].copy()
    partial[[25, 26, 27, 28, 15, 13, 14]] = np.nan                # knees, ankles, a wrist, elbows unknown
    out.append(LandmarkFrame(9, 0.9, partial))
    header = RecordingHeader((640, 480), 10.0, "test",
                             S.LevelCamera(model="pinhole").intrinsics((640, 480)) if camera else None)
    write_recording(path, header, out)
    with open(path, "a", encoding="utf-8") as fh:                 # a malformed line, then a good frame
        fh.write('{"seq": 10, "t": 1.0, "landmarks": [1, 2]}\n')
        fh.write(json.dumps(LandmarkFrame(11, 1.1, frames[11][1]).to_json()) + "\n")
    return path


@pytest.mark.parametrize("camera,projection", [(False, "auto"), (False, "orthographic"), (True, "auto")])
def test_posed_fit_writes_one_result_per_frame(tmp_path, camera, projection):
    rec = recording(tmp_path / "in.landmarks.jsonl", camera)
    out = tmp_path / "out.jsonl"
    p = posed("fit", rec, "-o", out, "--set", f"fitting.projection={projection}")
    assert p.returncode == 1, p.stderr  # one line was skipped
    assert f"{rec}:12: landmarks must be a list of 33 entries" in p.stderr
    lines = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["seq"] for r in lines] == [*range(10), 11]
    assert all(r["ok"] for r in lines[:8]) and lines[10]["ok"]
    assert lines[8] == {"seq": 8, "t": 0.8, "ok": False, "reason": "no person"}
    assert not lines[9]["ok"] and "left_knee" in lines[9]["reason"] and "right_ankle" in lines[9]["reason"]
    assert lines[1]["mode"] == "video"
    # without the header's camera: the daemon's assumed lens (perspective, no root_cam_m), unless orthographic
    assert lines[0]["projection"] == ("orthographic" if projection == "orthographic" else "perspective")
    assert lines[0].get("lens") == (None if projection == "orthographic" else "given" if camera else "assumed")
    assert ("root_cam_m" in lines[0]) == camera
    if camera or projection == "orthographic":   # the model the frames were rendered with: exact
        truth = S.sequence("stand_to_sit", 30.0).pose_at(0.7)
        assert abs(lines[7]["variables"]["theta_hp_l"] - truth.joints["theta_hp_l"]) < 1.0


def test_posed_fit_image_mode_to_stdout_and_missing_input(tmp_path):
    rec = recording(tmp_path / "in.landmarks.jsonl")
    p = posed("fit", rec, "--mode", "image", "--set", "fitting.restarts=3")
    lines = [json.loads(line) for line in p.stdout.splitlines()]
    assert len(lines) == 11 and {r.get("mode") for r in lines if r["ok"]} == {"image"}
    p = posed("fit", tmp_path / "nothing.landmarks.jsonl")
    assert p.returncode == 2 and "no such landmark recording" in p.stderr


def test_posed_calibrate(tmp_path):
    dims = S.body_dimensions(1.75)
    pose = S.STANDING.replace(theta_sh_l=0, theta_sh_r=0, theta_el_l=2, theta_el_r=2)
    frames = [LandmarkFrame(i, i / 10, S.render(pose, dims=dims, noise_px=1.0, seed=i)) for i in range(12)]
    rec = tmp_path / "stand.landmarks.jsonl"
    write_recording(rec, RecordingHeader((640, 480), 10.0, "stand"), frames)
    out = tmp_path / "me" / "user.yaml"
    p = posed("calibrate", rec, "-o", out, "--height", "1.75")
    assert p.returncode == 0, p.stderr
    data = yaml.safe_load(out.read_text())
    assert data["thigh_m"] == pytest.approx(dims.thigh_m, rel=0.03) and data["frames"] == 12
    write_recording(rec, RecordingHeader((640, 480), 10.0, "stand"), frames[:5])
    p = posed("calibrate", rec, "-o", tmp_path / "x.yaml", "--height", "1.75")
    assert p.returncode == 1 and "need 10" in p.stderr


def test_bench_fit_report_structure():
    from posed.bench import fit as bench
    from posed.bench.commands.fit import markdown
    from posed.fitting import FitConfig

    plan = bench.Plan(paper_yaws=(30.0,), floor_yaws=(90.0,), motion_yaws=(30.0,), seeds=(0,), motion_seeds=(0,),
                      settings=((6, 6),), noises=(0.0,), table3=False, sequences=("stand_to_sit",))
    report = bench.run(plan, FitConfig())
    assert set(report) == {"protocol", "machine", "results"}
    ref = report["machine"]["speed_ref_ms"]    # how fast the machine ran, before and after
    assert ref["before"] > 0 and ref["after"] > 0
    keys = {"optimizer", "restarts", "max_row", "mode", "noise_px", "angle_err_deg", "mpjpe3d_mm", "err2d", "loss",
            "evals", "ms_per_frame"}
    for r in report["results"]:
        assert keys <= set(r)
    full = [r for r in report["results"] if r["protocol"] == "paper_poses" and r["optimizer"] == "udeas+lm"][0]
    assert full["angle_err_deg"] < 1.0 and full["frames"] == 6
    video = [r for r in report["results"] if r["mode"] == "video"][0]
    assert video["frames"] == 120 and video["angle_err_deg"] < 1.0
    assert "| paper_poses | udeas+lm | (6, 6) |" in markdown(report)
    assert f"speed reference {ref['before']} ms before / {ref['after']} ms after" in markdown(report)
    json.dumps(report)


def test_posed_fit_puts_back_left_and_right_where_another_extractor_flipped_them(tmp_path, shared_data):
    """A recording another tool made (BlazePose full's own landmarks and world landmarks of the real squat
    video, tfjs-models) whose labels flip for three frames while the woman stands facing the camera: `posed
    fit` fits it exactly as the unflipped one (landmarks.sides, image and world landmarks together); with
    `landmarks.keep_sides=false`, or a header saying the sides were kept already, it takes them as they come."""
    from tests.landmarks import flipped_squat

    flipped = flipped_squat.FLIPPED

    def make(name, flip, extra=None):
        return flipped_squat.write(shared_data, tmp_path / name, flip, extra)

    def fits(path, *sets):
        run = posed("fit", path, "-o", "-", *sets)
        assert run.returncode == 0, run.stderr
        rows = [json.loads(line) for line in run.stdout.splitlines()]
        for r in rows:
            r.pop("fit_ms", None), r.pop("udeas_ms", None)
        return rows, run.stderr

    clean, _ = fits(make("clean.landmarks.jsonl", set()))
    put_back, said = fits(make("flipped.landmarks.jsonl", flipped))
    assert put_back == clean
    assert "left and right put back on 3" in said
    as_they_come, _ = fits(tmp_path / "flipped.landmarks.jsonl", "--set", "landmarks.keep_sides=false")
    kept_already, _ = fits(make("kept.landmarks.jsonl", flipped, {"sides_kept": True}))
    for rows in (as_they_come, kept_already):
        assert rows[:20] == clean[:20] and all(rows[i] != clean[i] for i in flipped)
        # the fitted left shoulder goes to the image's other side with the labels
        for i in flipped:
            assert np.sign(rows[i]["joints_3d"]["left_shoulder"][0]) != np.sign(clean[i]["joints_3d"]["left_shoulder"][0])
