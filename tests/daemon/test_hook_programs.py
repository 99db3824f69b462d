"""A hook whose program does not exist or is not executable is a config problem for ``posed config check``
(issue 34 item 8: it failed only at the first fall); ``posed run`` logs it and starts anyway."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from posed.daemon.config.schema import Config
from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.preflight import hook_program_problems

ROOT = Path(__file__).resolve().parents[2]


def _cfg(*argvs) -> Config:
    return Config(hooks=HooksConfig(on_event=tuple(HookConfig(argv=tuple(a)) for a in argvs)))


def test_missing_and_unexecutable_hook_programs_are_named(tmp_path):
    script = tmp_path / "notify.sh"
    script.write_text("#!/bin/sh\nexit 0\n")
    script.chmod(0o644)
    ok = tmp_path / "ok.sh"
    ok.write_text("#!/bin/sh\nexit 0\n")
    ok.chmod(0o755)
    problems = hook_program_problems(_cfg([str(tmp_path / "missing")], ["no-such-program-posed"], [str(script)],
                                          [str(ok)], [sys.executable, "-c", "pass"], ["sh", "-c", "true"]))
    assert len(problems) == 3, problems
    assert problems[0].startswith("hooks.on_event[0].argv[0]") and "does not exist" in problems[0]
    assert "on PATH" in problems[1]
    assert "not executable" in problems[2] and "chmod +x" in problems[2]


def test_config_check_exits_78_and_lists_them(tmp_path):
    r = subprocess.run([sys.executable, "-m", "posed.cli", "config", "check", "--set",
                        f"pipeline.state_dir={tmp_path / 'state'}", "--set",
                        f"hooks.on_event=[{{argv: [{tmp_path / 'missing'}]}}]"],
                       cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 78, (r.stdout, r.stderr)
    assert "hooks.on_event[0].argv[0]" in r.stderr and "would start" in r.stderr
