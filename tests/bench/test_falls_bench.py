"""The CMU BVH reader and the benchmark's plumbing (the real-fit numbers live in docs/bench/falls.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from posed.bench.bvh import CMU_UNIT_M, cmu_landmark_world, forward_kinematics, read_bvh
from posed.cli import main


def test_cmu_bvh_parses_to_a_plausible_rigid_body(shared_data):
    motion = read_bvh(shared_data / "mocap" / "cmu" / "131_01.bvh")
    assert motion.data.shape == (994, 96) and abs(motion.fps - 120.0) < 0.01
    pos, _rot, _ends = forward_kinematics(motion)
    hip, knee = motion.index("LeftHip"), motion.index("LeftKnee")
    thigh = np.linalg.norm(pos[:, knee] - pos[:, hip], axis=1) * CMU_UNIT_M
    assert np.ptp(thigh) < 1e-9 and 0.35 < thigh[0] < 0.45        # a rigid thigh of a human length
    world = cmu_landmark_world(motion, np.arange(0, 994, 12))
    nose = world[0]["nose"][2]
    assert 1.35 < nose < 1.7                                         # standing: nose ~0.93 H for H ~1.5-1.8 m
    pelvis = np.array([p["pelvis"][2] for p in world])
    crouch = int(np.argmin(pelvis))
    assert 2.8 < crouch * 0.1 < 3.6 and pelvis[crouch] < 0.5 * pelvis[0]   # the deep crouch near 3.2 s
    assert world[0]["left_hip"][0] > world[0]["right_hip"][0] - 1.0      # both hips mapped


def test_bench_json_schema_with_ground_truth_fits(capsys):
    code = main(["bench", "falls", "--truth", "--split", "cmu", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0
    assert set(report) >= {"scenarios", "recall", "false_alarms", "median_latency_s"}
    assert [s["name"] for s in report["scenarios"]] == ["cmu/131_01/side", "cmu/131_01/oblique",
                                                        "cmu/131_02/side", "cmu/131_02/oblique"]
    assert all(s["kind"] == "adl" and s["detected"] is False and s["latency_s"] is None
               for s in report["scenarios"])
    assert report["false_alarms"] == 0 and report["recall"] is None


def test_bench_reports_falls_and_latency(capsys):
    code = main(["bench", "falls", "--truth", "--split", "tune", "--only", "found-lying", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert len(report["scenarios"]) == 6 and report["recall"] == 1.0
    # found lying: reported on_floor_confirm_s (1 s) after the first frame; the exit status follows the targets
    assert 0.9 <= report["median_latency_s"] <= 1.5
    assert code == (0 if report["median_latency_s"] <= 1.0 else 1)


def test_real_fit_detects_a_fall_and_not_lying_on_a_bed():
    """End to end through fitting.fitter.Fitter (video mode, perspective): the detector's input as in the daemon."""
    from posed.bench.falls import real_fitter, run_case, scenario_cases
    from posed.falls.config import FallsConfig

    cases = {c.name: c for c in scenario_cases("tune")
             if c.name in ("tune/fall/standing-forward/fast-v100", "tune/adl/lie-on-bed-side/normal-v30")}
    fit = real_fitter()
    fall = run_case(cases["tune/fall/standing-forward/fast-v100"], fit, FallsConfig(), "auto")
    fit.reset()
    bed = run_case(cases["tune/adl/lie-on-bed-side/normal-v30"], fit, FallsConfig(), "auto")
    assert fall.detected and fall.states[0] == "falling" and 0.0 <= fall.latency_s <= 1.0
    assert not bed.detected and bed.states == []
    assert bed.min_pelvis_rel_lying is not None and bed.min_pelvis_rel_lying > 0.45


def test_a_wall_camera_without_intrinsics_is_fitted_through_the_assumed_lens():
    """--mount wall gives the fit what the daemon gives a source without intrinsics: the lens of
    falls.camera_hfov_deg, assumed (perspective, no root_cam_m), with or without the fit cache."""
    from posed.bench.falls import cached_fit, real_fitter, scenario_cases
    from posed.camera_model import Intrinsics

    case = next(c for c in scenario_cases("tune", "wall") if c.name.endswith("fall/standing-forward/fast-v100"))
    lens = Intrinsics.assume(69.0, case.camera.width, case.camera.height)
    fn = cached_fit(case, real_fitter(), None, None, lens)
    fr = next(f for f in case.frames if f.landmarks is not None)
    r = fn(fr.landmarks, fr.seq, fr.t, (case.camera.width, case.camera.height), None)
    assert r.ok and r.extra["projection"] == "perspective" and r.extra["lens"] == "assumed"
    assert r.root_cam_m is None


def test_the_world_stream_is_each_case_s_own_body_and_reaches_the_fit():
    """--world: every frame with landmarks gets BlazePose-like world landmarks of the case's true body (mid-hip
    origin, camera axes, the 12 body joints only), the same stream on every run, and the fit uses them."""
    from posed.bench.falls import real_fitter, run_case, scenario_cases
    from posed.bench.falls_world import case_world
    from posed.bench.mocap_landmarks import BODY12_IDX
    from posed.falls.config import FallsConfig

    case = next(c for c in scenario_cases("tune") if c.name == "tune/fall/standing-forward/fast-v100")
    world = case_world(case)
    assert len(world) == len(case.frames)
    assert all((w is None) == (fr.landmarks is None) for w, fr in zip(world, case.frames, strict=True))
    seen = [w for w in world if w is not None]
    others = np.setdiff1d(np.arange(33), BODY12_IDX)
    for w in seen:
        assert w.shape == (33, 5) and np.isfinite(w[BODY12_IDX]).all() and np.isnan(w[others, :3]).all()
        np.testing.assert_allclose(0.5 * (w[23, :3] + w[24, :3]), 0.0, atol=1e-12)      # hip-centred
    standing = seen[0]
    assert standing[27, 1] - standing[11, 1] > 1.0             # ankles a metre and more below the shoulders (y down)
    for a, b in zip(world, case_world(case), strict=True):     # seeded by the case: the same stream each run
        assert (a is None and b is None) or np.array_equal(a, b, equal_nan=True)

    given = []
    fit = real_fitter()

    def spy(lm, seq, t, size, intr, gravity=None, w=None):
        given.append(w)
        return fit(lm, seq, t, size, intr, gravity, w)

    outcome = run_case(case, spy, FallsConfig(), "auto", world=world)
    assert outcome.detected and len(given) == len(seen) and all(w is not None for w in given)
    fr = next(f for f in case.frames if f.landmarks is not None)
    fit.reset()
    r = fit(fr.landmarks, fr.seq, fr.t, (case.camera.width, case.camera.height), case.camera.intrinsics, None,
            world[case.frames.index(fr)])
    assert r.ok and "world" in r.extra["evidence"]
    fit.reset()
    assert "world" not in fit(fr.landmarks, fr.seq, fr.t, (case.camera.width, case.camera.height),
                              case.camera.intrinsics).extra["evidence"]


def _labelled_folder(shared_data, tmp_path, clips):
    import shutil

    src = shared_data / "falls" / "urfd_dev"
    labels = json.loads((src / "labels.json").read_text())
    labels["clips"] = [c for c in labels["clips"] if c["clip"] in clips]
    for c in clips:
        shutil.copy(src / f"{c}.landmarks.jsonl", tmp_path / f"{c}.landmarks.jsonl")
    (tmp_path / "labels.json").write_text(json.dumps(labels))
    return tmp_path


def test_bench_scores_labelled_real_recordings(shared_data, tmp_path, capsys):
    """`posed bench falls --recordings DIR`: a real fall found with its latency from the labelled impact, a
    real daily activity quiet; the same fit and detector as `posed falls`."""
    folder = _labelled_folder(shared_data, tmp_path, ["urfd_02_fall", "urfd_22_adl"])
    code = main(["bench", "falls", "--split", "none", "--recordings", str(folder), "--json", "--no-cache"])
    report = json.loads(capsys.readouterr().out)["recordings"]
    by = {c["name"]: c for c in report["clips"]}
    assert report["falls"] == 1 and report["adl"] == 1 and report["geometry"] == "labels"
    assert report["falls_config"] == {"camera_tilt_deg": 0.0, "camera_roll_deg": 0.0, "camera_height_m": 0.85}
    fall = by["urfd_02_fall"]
    assert fall["detected"] and fall["states"][0] == "falling" and abs(fall["latency_s"]) <= 1.0
    assert not by["urfd_22_adl"]["detected"] and by["urfd_22_adl"]["states"] == []
    assert report["recall"] == 1.0 and report["false_alarms"] == 0 and code == 0


def test_bench_recordings_folder_errors_name_the_problem(tmp_path):
    from posed.bench.falls_recordings import read_labels

    with pytest.raises(FileNotFoundError, match="labels.json"):
        read_labels(tmp_path)
    (tmp_path / "labels.json").write_text(json.dumps({"clips": [{"clip": "a", "label": "fell"}]}))
    with pytest.raises(ValueError, match="valid: fall, adl"):
        read_labels(tmp_path)
    (tmp_path / "labels.json").write_text(json.dumps({"clips": [{"clip": "a", "label": "fall"}]}))
    with pytest.raises(FileNotFoundError, match="a.landmarks.jsonl"):
        read_labels(tmp_path)


def test_synthetic_camera_geometry_modes(capsys):
    """--synthetic-geometry: the true tilt given, a mount nobody measured (tilt 0), and tilt 0 with an
    accelerometer's gravity on every frame; on ground-truth fits the IMU restores what the unknown mount loses
    (people found lying, never seen standing or sitting: nothing checks the level guess. The falls from a chair
    used here before are now all caught on the unknown mount too: in the one it lost, a camera 18 deg down and
    3.8 m away, the seated person's feet come out above the camera along the guess, which rejects it)."""
    out = {}
    for mode in ("given", "unknown", "imu"):
        main(["bench", "falls", "--truth", "--split", "tune", "--only", "fall/found-lying", "--json",
              "--synthetic-geometry", mode])
        report = json.loads(capsys.readouterr().out)
        assert report["geometry"]["mode"] == mode and report["geometry"]["meaning"]
        out[mode] = report["recall"]
    assert out["given"] == 1.0 and out["imu"] == 1.0
    assert out["unknown"] < 1.0


def test_wall_mount_with_the_default_config(capsys):
    """--mount wall renders the scenes through the wall camera (2 m, 35 deg, 320x240) and --synthetic-geometry
    default leaves the config as it is: the body check finds the falls from standing (ground-truth joints)."""
    code = main(["bench", "falls", "--truth", "--mount", "wall", "--synthetic-geometry", "default", "--split",
                 "tune", "--only", "fall/standing-sideways/fast", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert report["mount"] == "wall" and report["geometry"]["mode"] == "default"
    assert [s["name"] for s in report["scenarios"]] == ["wall/tune/fall/standing-sideways/fast-v30",
                                                        "wall/tune/fall/standing-sideways/fast-v100"]
    assert report["recall"] == 1.0 and code == 0


def test_the_corner_mount_keeps_the_whole_standing_body_in_view():
    """--mount corner (2.4 m, 25 deg, 320x240, 74 deg, people 3.0-4.2 m away): every landmark of a standing
    person, and of a person lying where a fall away from the camera ends, projects inside the image; the CLI
    renders it."""
    from posed.bench.falls import scenario_cases

    cases = {c.name: c for c in scenario_cases("tune", "corner")}
    assert cases and all(n.startswith("corner/tune/") for n in cases)
    for name in ("corner/tune/fall/standing-backward/fast-v30", "corner/tune/adl/sit-down-chair/normal-v30"):
        case = cases[name]
        assert (case.camera.z, case.camera.tilt, case.camera.width, case.camera.height) == (2.4, 25.0, 320, 240)
        for fr in (case.frames[0], case.frames[-1]):
            lm = np.asarray(fr.landmarks, float)
            body = lm[11:29]
            assert np.all(body[:, 0] > 0) and np.all(body[:, 0] < 320), name
            assert np.all(body[:, 1] > 0) and np.all(body[:, 1] < 240), name
    assert main(["bench", "falls", "--truth", "--mount", "corner", "--split", "tune", "--only",
                 "fall/standing-sideways/fast-v30", "--json"]) == 0


def test_cross_source_rows_and_gaps():
    from posed.bench.falls_cross import Row, table

    ref = Row("tune", "chosen on", "given", 36, 36, 52, 0, 0.7)
    other = Row("wall", "held out", "default config", 111, 33, 104, 3, 0.8)
    js = other.to_json(ref)
    assert js["recall_gap"] == round(33 / 111 - 1.0, 3) and js["false_alarm_rate_gap"] == round(3 / 104, 3)
    text = table({"rows": [ref.to_json(ref), js]})
    assert "| wall | held out | default config | 33/111 (29.7 %) | -70.3 | 3/104 | +2.9 | 0.8 |" in text
