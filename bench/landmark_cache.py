"""Names for cached landmark recordings that change with the landmark stage's code.

A benchmark that runs ``posed landmarks`` once and reuses the recording would otherwise keep measuring the
stage as it was when the file was made: :func:`stage_tag` is a short hash of ``landmarks/*.py``, put in the
cached file's name, so a changed stage makes a new recording.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

LANDMARKS_SOURCE = Path(__file__).resolve().parent.parent / "landmarks"


def stage_tag() -> str:
    """10 hex digits of a hash of the landmark stage's source files."""
    h = hashlib.sha1()
    for f in sorted(LANDMARKS_SOURCE.glob("*.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:10]
