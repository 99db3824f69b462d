"""Fall detection: pure logic on the stream of fits (no I/O, no clock but the capture timestamps).

:class:`FallDetector` turns each :class:`fitting.FitResult` (with its 2D landmarks) into :class:`FallEvent`
updates (``falling``, ``on_floor``, ``alarm``, ``recovered``); :class:`FallsConfig` is the ``falls`` config
section. Imports only numpy, :mod:`camera_model` and the public face of :mod:`fitting`.
"""

from posed.falls.config import FallsConfig
from posed.falls.detector import FallDetector, Sample
from posed.falls.event import FALL_STATES, FallEvent

__all__ = ["FALL_STATES", "FallDetector", "FallEvent", "FallsConfig", "Sample"]
