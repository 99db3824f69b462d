"""A robot upgraded from the first release keeps its /etc/posed/config.yaml: the first release's config.yaml
(tests/daemon/upgrade_config_3bf58c4.yaml, every key it had) is still valid and means the same. No key of
config.yaml has been renamed or removed since (checked over its git history); a change that renames or removes
one fails here and must make the loader name the new key. Guard tests, real CLI processes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
FIRST_RELEASE = Path(__file__).with_name("upgrade_config_3bf58c4.yaml")


def posed(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "posed.cli", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


def leaves(data: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in data.items():
        if isinstance(value, dict):
            out.update(leaves(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def test_the_first_releases_config_passes_the_check(tmp_path):
    r = posed("config", "check", str(FIRST_RELEASE), "--set", f"pipeline.state_dir={tmp_path / 'state'}")
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.strip().endswith(": OK")


def test_every_key_of_the_first_release_keeps_its_value(tmp_path):
    r = posed("config", "show", "--config", str(FIRST_RELEASE))
    assert r.returncode == 0, r.stderr
    effective = leaves(json.loads(r.stdout))
    old = leaves(yaml.safe_load(FIRST_RELEASE.read_text()))
    lost = sorted(k for k in old if k not in effective)
    assert lost == []
    changed = {k: (v, effective[k]) for k, v in old.items()
               if (list(effective[k]) if isinstance(effective[k], tuple) else effective[k]) != v}
    assert changed == {}
