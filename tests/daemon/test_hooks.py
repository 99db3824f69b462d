"""Hooks: argv without a shell, event JSON on stdin, POSED_EVENT_* variables, retries, timeouts, never blocking."""

from __future__ import annotations

import json
import sys
import textwrap
import time
from pathlib import Path

from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.outbox.hooks import HookRunner
from posed.falls.event import FallEvent

EVENT = FallEvent(id="abc123", robot="r1", state="falling", t_onset=1.0, t_impact=1.5, t_detect=2.0,
                  confidence=0.85, features=("pelvis_descent_fast", "trunk_horizontal"), wall_time="2024-01-01T00:00:00")


def script(tmp_path: Path, body: str) -> str:
    path = tmp_path / "hook.py"
    path.write_text(textwrap.dedent(body))
    return str(path)


RECORD = """
    import json, os, sys, time
    out = sys.argv[1]
    data = sys.stdin.read()
    gate = os.environ.get("GATE")  # a test holds the hook here until it creates this file (at most 30 s)
    deadline = time.monotonic() + 30
    while gate and not os.path.exists(gate) and time.monotonic() < deadline:
        time.sleep(0.01)
    env = {k: v for k, v in os.environ.items() if k.startswith("POSED_")}
    with open(out, "a") as fh:
        fh.write(json.dumps({"argv": sys.argv[2:], "stdin": data, "env": env}) + "\\n")
    print("hook ran for", env.get("POSED_EVENT_ID"))
    sys.exit(int(os.environ.get("EXIT", "0")))
"""


def runs(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def test_event_json_on_stdin_and_environment(tmp_path, capsys):
    out = tmp_path / "runs.jsonl"
    cfg = HooksConfig(on_event=(HookConfig(argv=(sys.executable, script(tmp_path, RECORD), str(out))),))
    with HookRunner(cfg) as runner:
        runner.submit(EVENT)
        assert runner.wait_idle(20)
    [run] = runs(out)
    assert json.loads(run["stdin"]) == EVENT.to_json()
    env = run["env"]
    assert env["POSED_EVENT_ID"] == "abc123" and env["POSED_EVENT_STATE"] == "falling"
    assert env["POSED_EVENT_ROBOT"] == "r1" and env["POSED_EVENT_FEATURES"] == "pelvis_descent_fast,trunk_horizontal"
    assert float(env["POSED_EVENT_T_IMPACT"]) == 1.5 and env["POSED_EVENT_CONFIDENCE"] == "0.850"
    assert env["POSED_HOOK_ATTEMPT"] == "1"
    log = capsys.readouterr().out
    assert "hook_done" in log and "hook ran for abc123" in log   # the hook's output is logged


def test_shell_metacharacters_stay_literal(tmp_path):
    out = tmp_path / "runs.jsonl"
    canary = tmp_path / "pwned"
    evil = ["; touch " + str(canary), "$(touch " + str(canary) + ")", "`touch " + str(canary) + "`",
            "a && touch " + str(canary), "*", "'\"", "| cat /etc/passwd", "\n--help"]
    cfg = HooksConfig(on_event=(HookConfig(argv=(sys.executable, script(tmp_path, RECORD), str(out), *evil)),))
    with HookRunner(cfg) as runner:
        runner.submit(EVENT)
        assert runner.wait_idle(20)
    [run] = runs(out)
    assert run["argv"] == evil
    assert not canary.exists()


def test_failing_hook_is_retried_then_given_up_without_blocking(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("EXIT", "3")
    gate = tmp_path / "gate"
    monkeypatch.setenv("GATE", str(gate))
    out = tmp_path / "runs.jsonl"
    cfg = HooksConfig(retry_delay_s=0.05, on_event=(
        HookConfig(argv=(sys.executable, script(tmp_path, RECORD), str(out)), retries=2),))
    with HookRunner(cfg) as runner:
        runner.submit(EVENT)
        # the hook cannot finish before the gate opens, so submit came back while the hook was still held:
        # it did not wait for it (a submit that waited would return only after the hook's 30 s and its run)
        assert runs(out) == [] and runner.pending() == 1
        gate.touch()
        assert runner.wait_idle(30)
        outcomes = list(runner.outcomes)
    assert [r["env"]["POSED_HOOK_ATTEMPT"] for r in runs(out)] == ["1", "2", "3"]
    assert [o.returncode for o in outcomes] == [3, 3, 3] and not any(o.ok for o in outcomes)
    log = capsys.readouterr().out
    assert log.count("hook_failed") == 3 and "hook_gave_up" in log


HANG = """
    import subprocess, sys, time
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    open(sys.argv[1], "w").write(str(child.pid))
    time.sleep(60)
"""


def test_hanging_hook_is_killed_with_its_children_and_other_hooks_go_on(tmp_path, monkeypatch):
    import os

    gate = tmp_path / "gate"
    monkeypatch.setenv("GATE", str(gate))  # holds the recording hook, not the hanging one
    pidfile = tmp_path / "child.pid"
    out = tmp_path / "runs.jsonl"
    cfg = HooksConfig(retry_delay_s=0.0, on_event=(
        HookConfig(argv=(sys.executable, script(tmp_path, HANG), str(pidfile)), timeout_s=1.0, retries=0),
        HookConfig(argv=(sys.executable, str(tmp_path / "rec.py"), str(out)), retries=0),
    ))
    (tmp_path / "rec.py").write_text(textwrap.dedent(RECORD))
    with HookRunner(cfg) as runner:
        runner.submit(EVENT)
        runner.submit(EVENT)
        assert runs(out) == [] and runner.pending() >= 2          # the pipeline never waits: both still held
        gate.touch()
        deadline = time.monotonic() + 15
        while len(runs(out)) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(runs(out)) == 2                                 # the other hook did not wait for the hang
        assert runner.wait_idle(20)
        timed_out = [o for o in runner.outcomes if o.hook == 0]
    assert len(timed_out) == 2 and all(o.timed_out for o in timed_out)
    child = int(pidfile.read_text())

    def alive() -> bool:
        try:
            os.kill(child, 0)
            with open(f"/proc/{child}/stat") as fh:
                return fh.read().split()[2] != "Z"
        except (ProcessLookupError, FileNotFoundError):
            return False

    # SIGKILL went to the hook's process group at its timeout; the kernel carries it out when the child is
    # next scheduled, which a loaded machine may delay: wait for it (a child outside the group never dies)
    deadline = time.monotonic() + 10
    while alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(), "the hook's child survived the timeout"


def test_missing_program_is_reported(tmp_path, capsys):
    cfg = HooksConfig(retry_delay_s=0.0, on_event=(HookConfig(argv=(str(tmp_path / "no-such-hook"),), retries=1),))
    with HookRunner(cfg) as runner:
        runner.submit(EVENT)
        assert runner.wait_idle(10)
        assert [o.ok for o in runner.outcomes] == [False, False]
        assert "cannot start" in runner.outcomes[0].error and "argv[0]" in runner.outcomes[0].error
    assert "hook_gave_up" in capsys.readouterr().out
