"""The whole configuration: ``yaml.safe_load`` -> frozen dataclasses, every problem reported at once.

``load_config(path, overrides=..., source=...)`` raises :class:`ConfigError` listing each problem with its
key path, the bad value and the valid choices or range; ``posed config check`` exits 78 (EX_CONFIG) on it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from posed.daemon.config.load import (
    ConfigError,
    ConfigProblem,
    apply_override,
    build,
    parse_yaml,
    read_config_bytes,
)
from posed.daemon.config.sections import (
    HooksConfig,
    LoggingConfig,
    PipelineConfig,
    PrivacyConfig,
    Ros2Config,
    WebConfig,
    ZenohConfig,
)
from posed.falls.config import FallsConfig
from posed.fitting import FitConfig
from posed.hal import SourceConfig
from posed.landmarks import LandmarkConfig

EX_CONFIG = 78
DEFAULT_CONFIG = Path(__file__).resolve().parents[2] / "config.yaml"


@dataclass(frozen=True)
class Config:
    """Root of config.yaml."""

    robot_id: str = field(
        default="robot1", metadata={"doc": "robot name used in every Zenoh key (posed/ROBOT/...)",
                                    "pattern": r"[A-Za-z0-9_\-]+"}
    )
    source: SourceConfig = SourceConfig()
    landmarks: LandmarkConfig = LandmarkConfig()
    fitting: FitConfig = FitConfig()
    pipeline: PipelineConfig = PipelineConfig()
    zenoh: ZenohConfig = ZenohConfig()
    falls: FallsConfig = FallsConfig()
    hooks: HooksConfig = HooksConfig()
    logging: LoggingConfig = LoggingConfig()
    web: WebConfig = WebConfig()
    ros2: Ros2Config = Ros2Config()
    privacy: PrivacyConfig = PrivacyConfig()


def source_override(uri: str) -> tuple[dict, list[ConfigProblem]]:
    """Translate a source URI (interfaces.md section 3) into ``source`` section keys."""
    scheme, sep, rest = uri.partition(":")
    if not sep:
        return {}, [ConfigProblem("--source", f"{uri!r} is not a URI; use realsense:[SERIAL], "
                                              "v4l2:/dev/videoN or file:PATH")]
    if scheme == "realsense":
        return {"type": "realsense", "serial": rest}, []
    if scheme == "v4l2":
        if not rest:
            return {}, [ConfigProblem("--source", "v4l2: needs a device, e.g. v4l2:/dev/video0")]
        return {"type": "v4l2", "device": rest}, []
    if scheme == "file":
        if not rest:
            return {}, [ConfigProblem("--source", "file: needs a path, e.g. file:video.mp4")]
        return {"type": "file", "path": rest}, []
    return {}, [ConfigProblem("--source", f"{scheme!r} is not one of: realsense, v4l2, file")]


def _embedded_text() -> str:
    from posed.daemon.config.doc import template  # doc imports this module

    return template()


def load_config(
    path: str | os.PathLike | None = None,
    overrides: list[str] | tuple[str, ...] = (),
    source: str | None = None,
) -> Config:
    """Read, override and validate a config file (None: the embedded default, config.yaml's text built from
    the code by ``daemon.config.doc.template``, so an installed wheel needs no file)."""
    embedded = path is None
    path = Path(path) if path is not None else DEFAULT_CONFIG
    origin = str(path.name if path == DEFAULT_CONFIG else path)
    try:
        raw = _embedded_text().encode() if embedded else read_config_bytes(path)
    except OSError as exc:
        raise ConfigError([ConfigProblem("", f"cannot read the config file: {exc.strerror}")], str(path)) from exc
    try:
        data, problems = parse_yaml(raw)          # not UTF-8, not YAML: raised; duplicate keys: listed
    except ConfigError as exc:
        raise ConfigError(exc.problems, origin) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError([ConfigProblem("", "the top level must be a mapping of sections")], origin)
    for assignment in overrides:
        problem = apply_override(data, assignment)
        if problem:
            problems.append(problem)
    if source:
        keys, bad = source_override(source)
        problems.extend(bad)
        if keys:
            section = data.get("source")
            data["source"] = {**(section if isinstance(section, dict) else {}), **keys}
    config = build(Config, data, "", problems)
    problems += cross_problems(config)
    if problems:
        raise ConfigError(problems, origin, partial=config)
    return config


def cross_problems(config: Config) -> list[ConfigProblem]:
    """What is wrong between keys that are each valid on their own (every command that loads the config
    rejects them, not only ``posed run``)."""
    f = config.fitting
    out = []
    for init, top in (("row_init", "row_max"), ("video_row_init", "video_row_max")):
        if getattr(f, init) > getattr(f, top):
            out.append(ConfigProblem(f"fitting.{init}", f"{getattr(f, init)} is more than fitting.{top} "
                                     f"({getattr(f, top)}); uDEAS grows the row from {init} up to {top}: lower "
                                     f"{init} or raise {top}"))
    if f.visibility_drop >= f.visibility_full:
        out.append(ConfigProblem("fitting.visibility_drop", f"{f.visibility_drop} is not below "
                                 f"fitting.visibility_full ({f.visibility_full}); landmark weights rise from 0 at "
                                 "visibility_drop to 1 at visibility_full: lower visibility_drop or raise "
                                 "visibility_full"))
    return out
