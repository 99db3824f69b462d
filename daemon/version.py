"""The version of posed: the one place it is written. pyproject.toml reads it from here (``[tool.setuptools.dynamic]``),
so ``posed --version``, the status object's ``version`` and every ``posed bench NAME --json`` report's
``posed_version`` match the installed distribution. A plain assignment: setuptools reads it without importing,
and the command line does not pay for ``importlib.metadata`` at every start.

:func:`version_text` adds what the robot runs beside the code: the landmark models' converter version, mediapipe
release and ONNX hashes, read from the models folder's manifest (nothing hashed)."""

__version__ = "0.1.0"


def version_text(models_dir: str = "") -> str:
    """``posed X`` and, on a second line, the landmark models in ``models_dir`` (default: the folder the daemon
    uses, ``landmarks.default_models_dir``) or why there are none."""
    from posed.landmarks import describe_models, installed_models

    return f"posed {__version__}\nlandmark models: {describe_models(installed_models(models_dir or None))}"
