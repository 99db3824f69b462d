"""Every problem of a config in one run: a key the schema rejects no longer hides the start-up checks (a
missing calibration file, a hook program that does not exist, missing models), and keys wrong between
themselves (row_init above row_max, visibility_drop not below visibility_full) are rejected by every command
that loads the config, not only by ``posed run``. Real CLI processes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RECORDING = "falls/urfd_dev/urfd_18_adl.landmarks.jsonl"


def posed(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def test_a_schema_problem_and_the_start_up_checks_are_listed_together(tmp_path, shared_data):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"""fitting:
  restarts: many
  calibration: {tmp_path / 'absent.yaml'}
  row_init: 8
  row_max: 5
hooks:
  on_event:
    - argv: ["{tmp_path / 'no-such-program'}"]
    - argv: "not a list"
""")
    for args in (("config", "check", str(cfg)),
                 ("run", "--config", str(cfg), "--source", f"file:{shared_data / RECORDING}",
                  "--set", f"pipeline.state_dir={tmp_path / 'state'}")):
        r = posed(*args)
        assert r.returncode == 78, r.stdout + r.stderr
        err = r.stderr
        assert "fitting.restarts" in err                                       # the schema's
        assert "hooks.on_event[1].argv" in err
        assert "fitting.row_init: 8 is more than fitting.row_max (5)" in err  # between keys
        assert f"fitting.calibration: {tmp_path / 'absent.yaml'}" in err       # start-up checks, same run
        assert str(tmp_path / "no-such-program") in err
        assert "5 problem(s)" in err, err
        assert "stage_start" not in r.stdout


def test_a_wrong_key_is_not_checked_again_at_its_default(tmp_path):
    """landmarks.models_dir given as a number is the schema's problem; the models are not then looked for in
    the default folder and reported as a second problem about a folder the user never named."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text("landmarks:\n  models_dir: 12\n")
    r = posed("config", "check", str(cfg), "--set", f"landmarks.models_dir={tmp_path / 'none'}")
    assert r.returncode == 78
    r = posed("config", "check", str(cfg))
    assert r.returncode == 78 and "landmarks.models_dir" in r.stderr
    assert "1 problem(s)" in r.stderr, r.stderr


def test_keys_wrong_between_themselves_stop_every_command(tmp_path, shared_data):
    for sets in (("fitting.row_init=10", "fitting.row_max=2"),
                 ("fitting.video_row_init=9", "fitting.video_row_max=3"),
                 ("fitting.visibility_drop=0.8", "fitting.visibility_full=0.5")):
        args = [a for s in sets for a in ("--set", s)]
        r = posed("fit", str(shared_data / RECORDING), "-o", str(tmp_path / "f.jsonl"), *args)
        assert r.returncode == 78, (sets, r.stdout + r.stderr)
        assert sets[0].split("=")[0] in r.stderr and sets[1].split("=")[0] in r.stderr, r.stderr
        assert not (tmp_path / "f.jsonl").exists() or (tmp_path / "f.jsonl").stat().st_size == 0


def test_a_sections_own_cross_check_names_its_key_and_keeps_the_rest_checked(tmp_path):
    """A section whose ``__post_init__`` rejects keys together (client mode without a router, a reconnect
    ceiling below its start, a member named twice, a short token) is blamed on those keys, one problem each,
    and its other keys are still checked as written: the section used to be replaced by its defaults, so
    ``zenoh.config_file`` naming a missing file went unreported until the first problem was fixed."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"""source:
  reconnect_initial_s: 5
  reconnect_max_s: 1
zenoh:
  mode: client
  config_file: {tmp_path / 'nope.json5'}
web:
  token: short
falls:
  household:
    - {{name: anna, height_m: 1.6}}
    - {{name: anna, height_m: 1.7}}
""")
    r = posed("config", "check", str(cfg))
    assert r.returncode == 78, r.stdout + r.stderr
    lines = [line.split(": ", 1)[1] for line in r.stderr.splitlines() if line.startswith(f"{cfg}: ")]
    keys = [line.split(":", 1)[0] for line in lines]
    assert keys == ["source.reconnect_max_s", "zenoh.connect", "falls.household", "web.token",
                    "zenoh.config_file"], r.stderr
    assert "or use mode: peer" in lines[1] and "named twice: anna" in lines[2]      # one problem, whole
    assert "nope.json5 does not exist" in lines[4]
    assert "5 problem(s)" in r.stderr
