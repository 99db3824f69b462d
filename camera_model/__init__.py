"""The camera model every package shares: one pinhole intrinsics type and the capture-time names.

Dependency-free (the standard library and numpy): hal, landmarks, fitting, falls, the daemon and bench all
import it. See :mod:`camera_model.intrinsics` for the frames, the units and the capture-time convention.
"""

from posed.camera_model.intrinsics import Intrinsics

__all__ = ["Intrinsics"]
