"""Operations from the command line: which config every command reads, where read-only commands find the
state, the endpoint clients use, `--version` and the version in `posed bench --json`, the warm-up before the
first fit, `--set` examples that fit the command, and `file:...?loop=true` for `posed run`."""

from __future__ import annotations

import argparse
import json
import threading
import types
from pathlib import Path

import pytest

from posed.cli import build_parser, main
from posed.commands import config_from_args, config_path
from posed.daemon.config import load_config
from posed.daemon.config.paths import SERVICE_STATE_DIR, config_file, reading_state_dir
from posed.daemon.config.sections import PipelineConfig
from posed.daemon.version import __version__, version_text

ROOT = Path(__file__).resolve().parents[2]


def test_config_resolution_order(tmp_path):
    system = tmp_path / "etc" / "config.yaml"
    assert config_file(None, {}, system) is None                                   # embedded default
    system.parent.mkdir()
    system.write_text("robot_id: service\n")
    assert config_file(None, {}, system) == system                                 # /etc/posed/config.yaml
    assert config_file(None, {"POSED_CONFIG": "/x.yaml"}, system) == Path("/x.yaml")  # $POSED_CONFIG
    assert config_file("/y.yaml", {"POSED_CONFIG": "/x.yaml"}, system) == Path("/y.yaml")  # --config


def test_every_command_reads_the_config_named_by_posed_config(tmp_path, monkeypatch, capsys):
    cfg = tmp_path / "mine.yaml"
    cfg.write_text("robot_id: from_env\n")
    monkeypatch.setenv("POSED_CONFIG", str(cfg))
    assert main(["config", "show"]) == 0
    assert json.loads(capsys.readouterr().out)["robot_id"] == "from_env"
    args = argparse.Namespace(config=None, overrides=["robot_id=over"])
    assert config_path(args) == cfg and config_from_args(args).robot_id == "over"
    monkeypatch.setenv("POSED_CONFIG", str(tmp_path / "missing.yaml"))
    assert main(["config", "show"]) == 78
    assert "missing.yaml" in capsys.readouterr().err


def test_the_embedded_default_is_the_documented_config_yaml(monkeypatch):
    from posed.daemon.config.doc import template

    monkeypatch.delenv("POSED_CONFIG", raising=False)
    assert load_config(None) == load_config(ROOT / "config.yaml") == load_config(None, overrides=[])
    import yaml

    assert yaml.safe_load(template())["robot_id"] == load_config(None).robot_id


def test_read_only_commands_find_the_service_state(tmp_path):
    service = tmp_path / "var-lib-posed"
    home = tmp_path / "home"
    env = {"HOME": str(home)}
    own = home / ".local" / "state" / "posed"
    system = tmp_path / "config.yaml"
    kw = dict(environ=env, service_dir=service, system_config=system)
    # no service installed: the user's own folder
    assert reading_state_dir(PipelineConfig(), None, "events.sqlite3", **kw) == own
    service.mkdir()
    # only the service's folder exists: it is read
    assert reading_state_dir(PipelineConfig(), None, "events.sqlite3", **kw) == service
    own.mkdir(parents=True)
    (own / "events.sqlite3").write_bytes(b"")
    # the user has their own journal (a `posed run` by hand): theirs, unless the service's config is in use
    assert reading_state_dir(PipelineConfig(), None, "events.sqlite3", **kw) == own
    assert reading_state_dir(PipelineConfig(), system, "events.sqlite3", **kw) == service
    # an explicit state dir always wins
    assert reading_state_dir(PipelineConfig(state_dir=str(tmp_path / "x")), system, "events.sqlite3",
                             **kw) == tmp_path / "x"
    assert reading_state_dir(PipelineConfig(), system, "e", environ={"STATE_DIRECTORY": "/s"},
                             service_dir=service, system_config=system) == Path("/s")
    assert SERVICE_STATE_DIR == Path("/var/lib/posed")


def test_clients_reach_the_daemon_where_it_listens():
    from posed.daemon.bus.session import daemon_endpoints

    cfg = load_config(None)
    assert daemon_endpoints(cfg.zenoh) == ("tcp/127.0.0.1:7447",)
    cfg = load_config(None, overrides=["zenoh.listen=[tcp/0.0.0.0:7450, tcp/192.168.1.5:7451]"])
    assert daemon_endpoints(cfg.zenoh) == ("tcp/127.0.0.1:7450", "tcp/192.168.1.5:7451")
    cfg = load_config(None, overrides=["zenoh.listen=[]", "zenoh.connect=[tcp/10.0.0.1:7447]", "zenoh.mode=client"])
    assert daemon_endpoints(cfg.zenoh) == ("tcp/10.0.0.1:7447",)


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    first, *rest = capsys.readouterr().out.splitlines()
    assert first == f"posed {__version__}"
    # which models the robot runs (fails without it: the version alone): converter, mediapipe, hashes, or why none
    assert len(rest) == 1 and rest[0].startswith("landmark models: "), rest
    assert rest[0] == version_text().splitlines()[1]
    from importlib import metadata

    assert __version__ == metadata.version("posed")            # pyproject reads it from daemon/version.py


def test_every_bench_json_carries_the_version(monkeypatch, capsys):
    """`posed bench NAME --json` adds posed_version to what the benchmark prints (one object, indented or not,
    or one object per line); a benchmark that prints something else is passed on unchanged."""
    import posed.commands.bench as bench_cmd

    outputs = [json.dumps({"fps": 10.0}), json.dumps({"a": 1}, indent=2), '{"n": 1}\n{"n": 2}', "plain text"]

    def fake(text):
        return types.SimpleNamespace(__doc__="fake", add_arguments=lambda p: None,
                                     run=lambda a: print(text) or 0)

    name = bench_cmd.names()[0]
    real = bench_cmd.importlib.import_module
    for text in outputs:
        monkeypatch.setattr(bench_cmd.importlib, "import_module",
                            lambda mod, text=text: fake(text) if mod.startswith("posed.bench.commands.") else real(mod))
        assert main(["bench", name, "--json"]) == 0
        out = capsys.readouterr().out
        if text == "plain text":
            assert out == "plain text\n"
            continue
        objs = [json.loads(line) for line in out.splitlines()] if "\n{" in text else [json.loads(out)]
        assert all(o["posed_version"] == __version__ for o in objs)
        assert [{k: v for k, v in o.items() if k != "posed_version"} for o in objs] == (
            [json.loads(x) for x in text.splitlines()] if "\n{" in text else [json.loads(text)])


def test_warm_fitter_says_it_is_compiling_only_when_it_takes_long():
    from posed.commands.warmup import warm_fitter

    said: list[str] = []
    release = threading.Event()

    class SlowFitter:                       # a cold numba cache: the warm-up takes a while
        def warmup(self):
            assert release.wait(30)

    def say(msg):
        said.append(msg)
        release.set()                       # the notice came while the warm-up was still running

    warm_fitter(SlowFitter(), say, after_s=0.05)
    assert len(said) == 1 and "compiling the fitting kernels" in said[0] and "posed warmup" in said[0]

    said.clear()

    class QuickFitter:                      # a warm cache
        def warmup(self):
            pass

    warm_fitter(QuickFitter(), said.append, after_s=30.0)
    assert said == []


def test_posed_fit_compiles_before_the_first_frame(tmp_path, monkeypatch, capsys):
    """frame 0's fit_ms is the fit alone: `posed fit` warms the fitter up before fitting anything."""
    from posed import fitting

    calls: list[str] = []
    real = fitting.Fitter

    class Recording(real):
        def warmup(self):
            calls.append("warmup")
            super().warmup()

        def fit(self, *a, **kw):
            calls.append("fit")
            return super().fit(*a, **kw)

    monkeypatch.setattr(fitting, "Fitter", Recording)
    rec = tmp_path / "one.landmarks.jsonl"
    from posed.bench import simulate
    from posed.landmarks import LandmarkFrame, RecordingHeader, write_recording

    lm = simulate.render(simulate.pose("stand_arms_front"))
    write_recording(rec, RecordingHeader((640, 480), 10.0), [LandmarkFrame(0, 0.0, lm), LandmarkFrame(1, 0.1, lm)])
    assert main(["fit", str(rec), "-o", str(tmp_path / "out.jsonl")]) == 0
    fit_calls = [i for i, c in enumerate(calls) if c == "fit"]
    last_warmup = max(i for i, c in enumerate(calls) if c == "warmup")
    assert len(fit_calls) >= 2 and last_warmup < fit_calls[-2]     # the warm-up's own fits, then the frames
    assert calls[-2:] == ["fit", "fit"]


def test_set_examples_name_a_section_the_command_reads():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    uses_fitting = {"run", "demo", "fit", "calibrate", "warmup", "config", "falls", "render", "record"}
    for name, cmd in sub.choices.items():
        for action in cmd._actions:
            if "--set" in action.option_strings and name not in uses_fitting:
                assert "fitting." not in (action.help or ""), f"posed {name}: --set help names fitting"


def test_config_check_set_and_bench_phase_have_help():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    check = next(a for a in sub.choices["config"]._actions if isinstance(a, argparse._SubParsersAction))
    set_help = [a.help for a in check.choices["check"]._actions if "--set" in a.option_strings]
    assert set_help and set_help[0]
    import posed.bench.commands.pipeline as pipeline

    p = argparse.ArgumentParser()
    pipeline.add_arguments(p)
    assert [a.help for a in p._actions if "--phase" in a.option_strings][0]


def test_run_accepts_a_file_uri_with_loop(shared_data):
    """`--source file:VIDEO?loop=true` is what the docs show: preflight checks the file, not 'VIDEO?loop=true'."""
    from posed.daemon.preflight import check

    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    cfg = load_config(None, source=f"file:{video}?loop=true&realtime=false")
    assert not [p for p in check(cfg) if p.startswith("source")]
    cfg = load_config(None, source=f"file:{video}?lop=true")
    assert any("lop" in p for p in check(cfg))
    cfg = load_config(None, source=f"file:{video}.missing?loop=true")
    assert any("does not exist" in p for p in check(cfg))


def test_watch_says_what_a_starting_daemon_is_doing():
    from posed.commands._viewer import Summary, waiting_for

    status = {"state": "starting", "stages": {"capture": {"state": "running"}, "landmarks": {"state": "running"},
                                              "fitting": {"state": "starting"}}}
    assert "compiling the fitting kernels" in waiting_for(status)
    assert waiting_for(None) == "waiting for the daemon"
    assert waiting_for({"state": "degraded", "stages": {}}) == "degraded"
    s = Summary()
    s.status = status
    assert "no poses (starting: compiling the fitting kernels" in s.line(1.0)[-1]


def test_watch_counts_frames_not_poses_and_says_whose_fall_with_several_people():
    import json as _json
    from types import SimpleNamespace

    from posed.commands._viewer import Summary

    def sample(obj):
        return SimpleNamespace(payload=SimpleNamespace(to_string=lambda: _json.dumps(obj)))

    from posed.fitting import FitResult
    from posed.fitting.measured import Measured

    def pose(seq, person, knee):
        r = FitResult(seq, seq / 10, True, joint_angles_deg={"theta_kn_l": knee}, extra={"person": person},
                      measured=Measured.from_landmarks(["left_hip", "left_knee", "left_ankle"]))
        return {**r.to_json(), "timing_ms": {"total": 20.0}}

    s = Summary()
    for seq in range(10):                    # one second at 10 fps, two people in each frame
        s.on_pose(sample(pose(seq, 1, 10.0)))
        s.on_pose(sample(pose(seq, 2, 80.0)))
    s.on_event(sample({"id": "e" * 32, "state": "on_floor", "confidence": 0.8, "features": [], "person": 2,
                       "member": "Grandma"}))
    fall, line = s.line(1.0)
    assert "10.0 fps" in line and "2 people" in line and "knee L  10.0" in line, line
    assert "person 2 (Grandma)" in fall


def test_landmarks_progress_lines(capsys):
    from posed.commands.landmarks import Progress

    p = Progress(total=10, period_s=0.0)
    p.frame(3, 2)
    p.end()
    err = capsys.readouterr().err
    assert err.startswith("posed landmarks: frame 3/10 (30 %)") and "person in 2" in err and "left" in err
    q = Progress(total=1, period_s=0.0)            # one image: no progress line
    q.frame(1, 1)
    assert capsys.readouterr().err == ""


def test_models_fetch_without_the_convert_extra_names_it(tmp_path):
    """A runtime-only install (no tflite): `posed models fetch` says which package is missing and which extra
    installs it. The missing package is simulated by a module that cannot be imported, first on the path."""
    import os
    import subprocess
    import sys

    shadow = tmp_path / "shadow"
    shadow.mkdir()
    (shadow / "tflite.py").write_text("raise ModuleNotFoundError(\"No module named 'tflite'\", name='tflite')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(shadow), str(ROOT)])}
    r = subprocess.run([sys.executable, "-m", "posed.cli", "models", "fetch", "--models-dir", str(tmp_path / "m")],
                       capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)
    assert r.returncode == 69, r.stdout + r.stderr
    assert "'tflite'" in r.stderr and "pip install 'posed[convert]'" in r.stderr
    assert not (tmp_path / "m").exists()
