import subprocess
import sys
from dataclasses import FrozenInstanceError
from pathlib import Path

import pytest

from posed.cli import main
from posed.daemon.config import EX_CONFIG, Config, load_config
from posed.daemon.config import doc as configdoc
from posed.daemon.config.load import ConfigError

ROOT = Path(__file__).resolve().parents[2]


def test_embedded_default_loads_and_is_frozen():
    cfg = load_config(ROOT / "config.yaml")
    assert isinstance(cfg, Config)
    assert cfg == Config()
    with pytest.raises(FrozenInstanceError):
        cfg.robot_id = "x"  # type: ignore[misc]


def test_config_yaml_is_the_generated_template_and_docs_match():
    assert (ROOT / "config.yaml").read_text() == configdoc.template(), "run: posed config template > config.yaml"
    assert (ROOT / "docs" / "config.md").read_text() == configdoc.reference(), "run: posed config doc > docs/config.md"


def test_every_key_is_documented():
    from posed.daemon.config.load import describe

    for path, _type, _default, _limits, doc in describe(Config):
        assert doc, f"{path} has no doc"


THREE_MISTAKES = """
source:
  type: realsens
fitting:
  restarts: -3
landmarks:
  colour: red
"""


def test_three_mistakes_all_reported(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(THREE_MISTAKES)
    with pytest.raises(ConfigError) as err:
        load_config(bad)
    text = str(err.value)
    assert len(err.value.problems) == 3
    assert "bad.yaml: source.type: 'realsens' is not one of: realsense, v4l2, file" in text
    assert "fitting.restarts: -3 is out of range [1, 200]" in text
    assert "landmarks.colour: unknown key; valid keys here: models_dir" in text


def test_config_check_cli_exit_codes(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(THREE_MISTAKES)
    assert main(["config", "check", str(bad)]) == EX_CONFIG
    err = capsys.readouterr().err
    assert err.count("bad.yaml: ") == 3
    assert main(["config", "check", str(ROOT / "config.yaml")]) == 0


def test_config_check_as_a_real_process(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("robot_id: 'has space'\nzenoh: {mode: router}\n")
    proc = subprocess.run([sys.executable, "-m", "posed.cli", "config", "check", str(bad)],
                          capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 78
    assert "robot_id: 'has space' does not match" in proc.stderr
    assert "zenoh.mode: 'router' is not one of: peer, client" in proc.stderr


@pytest.mark.parametrize("text, expected", [
    ("source: [1, 2]", "source: expected a mapping"),
    ("fitting: {restarts: 2.5}", "fitting.restarts: 2.5 is not an integer"),
    ("landmarks: {smoothing: 'yes'}", "landmarks.smoothing: 'yes' is not a boolean"),
    ("zenoh: {listen: 'tcp/1.2.3.4:1'}", "zenoh.listen: expected a list"),
    ("hooks: {on_event: [{argv: [notify], timeout_s: 0}]}", "hooks.on_event[0].timeout_s: 0.0 is out of range"),
    ("- a\n- b", "the top level must be a mapping"),
    ("a: [", "not valid YAML"),
])
def test_type_errors_name_path_and_value(tmp_path, text, expected):
    f = tmp_path / "c.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(f)
    assert expected in str(err.value)


def test_overrides_and_source_uri(tmp_path):
    cfg = load_config(ROOT / "config.yaml", overrides=["fitting.restarts=10", "robot_id=kitchen"],
                      source="v4l2:/dev/video2")
    assert cfg.fitting.restarts == 10 and cfg.robot_id == "kitchen"
    assert cfg.source.type == "v4l2" and cfg.source.device == "/dev/video2"
    assert load_config(ROOT / "config.yaml", source="realsense:123").source.serial == "123"
    with pytest.raises(ConfigError) as err:
        load_config(ROOT / "config.yaml", overrides=["fitting.restarts=zero", "nokey"], source="usb:3")
    text = str(err.value)
    assert "fitting.restarts: 'zero' is not an integer" in text
    assert "'nokey' is not of the form key.path=value" in text
    assert "'usb' is not one of: realsense, v4l2, file" in text


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read the config file"):
        load_config(tmp_path / "nope.yaml")


def test_a_bare_yaml_off_means_the_choice_off_where_the_key_has_it(tmp_path):
    """YAML 1.1 reads ``off`` as false: ``source.infrared: off`` (the natural way to write it) means the choice
    "off", in a file and in --set; a key without that choice says to quote the word."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text("source:\n  infrared: off\n")
    assert load_config(cfg).source.infrared == "off"
    assert load_config(None, overrides=["source.infrared=off"]).source.infrared == "off"
    assert load_config(None, overrides=['source.infrared="always"']).source.infrared == "always"
    cfg.write_text("source:\n  type: off\n  infrared: on\n")
    with pytest.raises(ConfigError) as err:
        load_config(cfg)
    text = str(err.value)
    assert "source.type: False is not a string (YAML reads a bare off" in text and 'quote the word' in text
    assert "source.infrared: True is not a string" in text        # "on" is not one of its choices either
