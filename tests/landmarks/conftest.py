"""Fixtures of the landmark tests. The converted models must be in place (``posed models fetch``, which
``make test`` runs first): without them the tests fail, never skip."""

from __future__ import annotations

from pathlib import Path

import pytest

from posed.landmarks import ModelMissingError, default_models_dir, find_models, verify_models
from tests.hal.conftest import squat_db3, squat_frames, squat_video  # noqa: F401 (a RealSense .db3 with depth)


@pytest.fixture(scope="session")
def models_dir() -> Path:
    """The checked models folder ($POSED_MODELS_DIR, else $XDG_CACHE_HOME/posed/models)."""
    folder = default_models_dir()
    try:
        verify_models(find_models(folder), include_tflite=True)
    except ModelMissingError as exc:
        pytest.fail(f"the landmark tests need the converted models: {exc}. "
                    f"Run `posed models fetch` (`make models`) before the tests.", pytrace=False)
    return folder
