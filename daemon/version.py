"""The version of posed: the one place it is written. pyproject.toml reads it from here (``[tool.setuptools.dynamic]``),
so ``posed --version``, the status object's ``version`` and every ``posed bench NAME --json`` report's
``posed_version`` match the installed distribution. A plain assignment: setuptools reads it without importing,
and the command line does not pay for ``importlib.metadata`` at every start."""

__version__ = "0.1.0"
