"""``posed bench landmarks --json``: one short real run (the numbers themselves live in docs/bench)."""

import json

import pytest

from posed.cli import main


def test_bench_json_has_both_back_ends_per_thread_count(models_dir, monkeypatch, capsys):
    monkeypatch.setenv("POSED_MODELS_DIR", str(models_dir))
    assert main(["bench", "landmarks", "--json", "--frames", "3", "--passes", "1", "--threads", "1"]) == 0
    report = json.loads(capsys.readouterr().out)
    entry = report["threads"]["1"]
    for model in ("landmark_model", "landmark_model_full_graph", "detector"):
        r = entry[model]
        assert r["onnx_ms"] > 0 and r["litert_ms"] > 0
        assert r["ratio"] == pytest.approx(r["onnx_ms"] / r["litert_ms"])
    tracking = entry["stage_per_frame"]["tracking"]
    assert set(tracking["onnx"]["steps_ms"]) >= {"crop", "landmark_model", "decode", "smoothing"}
    assert tracking["onnx"]["detector_runs_per_pass"] == 1
    assert entry["stage_per_frame"]["detection"]["onnx"]["detector_runs_per_pass"] == 3
    assert isinstance(entry["targets"]["landmark_model_onnx_le_litert"], bool)
