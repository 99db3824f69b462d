"""YAML aliases in a config (issue 34 item 5): one that refers to itself (``a: &a [*a]``, 11 bytes) and an alias
bomb (a "billion laughs") are config problems — exit 78 at once, in ``posed config check`` and ``posed run`` —
never a traceback or minutes at 100 % CPU; an ordinary alias still works."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.daemon.config.load import ConfigError, apply_override, parse_yaml

ROOT = Path(__file__).resolve().parents[2]


def _bomb(levels: int = 9) -> str:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    prev = "a"
    for c in "bcdefghijk"[:levels - 1]:
        lines.append(f"{c}: &{c} [" + ",".join([f"*{prev}"] * 9) + "]")
        prev = c
    return "\n".join(lines) + "\n"


def test_a_self_referring_alias_is_a_config_problem():
    with pytest.raises(ConfigError) as err:
        parse_yaml(b"a: &a [*a]\n")
    assert "refers to the list or mapping that holds it" in str(err.value)


def test_an_alias_bomb_is_refused_before_it_is_expanded():
    t0 = time.monotonic()
    with pytest.raises(ConfigError) as err:
        parse_yaml(_bomb().encode())
    assert "alias bomb" in str(err.value)
    assert time.monotonic() - t0 < 10.0          # 9^9 values: hours and gigabytes when expanded


def test_ordinary_aliases_still_work_and_report_duplicates_once():
    data, problems = parse_yaml(b"x: &h {argv: [/bin/true], timeout_s: 5}\ny: [*h, *h]\n")
    assert data["y"] == [{"argv": ["/bin/true"], "timeout_s": 5}] * 2 and problems == []
    _, problems = parse_yaml(b"x: &h {a: 1, a: 2}\ny: [*h, *h, *h]\n")
    assert len(problems) == 1 and problems[0].path == "x.a"


def test_an_override_with_a_self_referring_alias_is_a_problem():
    problem = apply_override({}, "hooks.on_event=&a [*a]")
    assert problem is not None and "refers to" in problem.message


@pytest.mark.parametrize("text", ["a: &a [*a]\n", _bomb()], ids=["self", "bomb"])
@pytest.mark.parametrize("command", [["config", "check"], ["run", "--config"]], ids=["check", "run"])
def test_the_commands_exit_78_quickly(tmp_path, text, command):
    path = tmp_path / "r.yaml"
    path.write_text(text)
    argv = [sys.executable, "-m", "posed.cli", *command, str(path)]
    t0 = time.monotonic()
    r = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 78, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and "alias" in r.stderr
    assert time.monotonic() - t0 < 60
