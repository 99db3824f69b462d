"""The daemon's configuration, one package: the schema (``schema``: the root ``Config`` composed of every
package's section, and the daemon's own sections in ``sections``), loading and validation (``load``: yaml ->
frozen dataclasses, every problem with its key path), the generated documentation (``doc``) and the state
files' paths (``paths``)."""

from posed.daemon.config.load import ConfigError, ConfigProblem
from posed.daemon.config.schema import DEFAULT_CONFIG, EX_CONFIG, Config, load_config

__all__ = ["DEFAULT_CONFIG", "EX_CONFIG", "Config", "ConfigError", "ConfigProblem", "load_config"]
