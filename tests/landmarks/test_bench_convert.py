"""``posed bench convert --json``: one real run (the numbers themselves live in docs/benchmarks.md)."""

import json

from daemon.cli import main


def test_bench_json_has_every_kept_output_of_both_models_per_input(models_dir, monkeypatch, capsys):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    assert main(["bench", "convert", "--json", "--random", "1", "--no-exact"]) == 0
    report = json.loads(capsys.readouterr().out)
    rows = report["rows"]
    inputs = {"pose.jpg", "sitting", "random 0"} | {f"squat frame {i}" for i in (0, 16, 32, 48, 64)}
    for model, outputs in (("pose_detection", {"Identity", "Identity_1"}),
                           ("pose_landmark_full", {"Identity", "Identity_1", "Identity_3", "Identity_4"})):
        mine = [r for r in rows if r["model"] == model]
        assert {r["input"] for r in mine} == inputs
        assert {r["output"] for r in mine} == outputs  # the segmentation head is not in the shipped model
        assert len(mine) == len(inputs) * len(outputs)
    for r in rows:
        assert r["within_target"] == (max(r["onnx_vs_builtin"], r["onnx_vs_xnnpack"]) <= 1e-3)
        assert r["exact_error"] is None
        assert r["max_abs_value"] > 0 or r["output"] == "Identity_1"
    assert report["pairs"] == len(rows)
    assert report["pairs_within_target"] == sum(r["within_target"] for r in rows)
    # onnxruntime and LiteRT agree to float32 noise on a real image: a converter bug is 10^4 times larger
    assert all(r["onnx_vs_builtin"] < 5e-3 for r in rows if r["input"] == "pose.jpg")
