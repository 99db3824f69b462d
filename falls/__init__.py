"""Fall detection: pure logic on the stream of fits (no I/O, no clock but the capture timestamps).

:class:`FallDetector` turns each :class:`fitting.FitResult` (with its 2D landmarks) into :class:`FallEvent`
updates (``falling``, ``on_floor``, ``alarm``, ``recovered``); :class:`PeopleFalls` runs one per person and
says who is who (:class:`Household`, by :func:`stature_m`); :func:`usual_absence` learns from the watched
:class:`Minutes` how long the person is usually out of view (:mod:`falls.absence`); :class:`FallsConfig` is
the ``falls`` config section. Imports only numpy, :mod:`camera_model` and the public face of :mod:`fitting`.
"""

from posed.falls.absence import SEEN_S, Minutes, Usual, last_seen, usual_absence, watched_between
from posed.falls.config import FallsConfig, HouseholdMember
from posed.falls.detector import FallDetector, Sample
from posed.falls.event import FALL_STATES, FallEvent
from posed.falls.household import Household
from posed.falls.people import PeopleFalls
from posed.falls.stature import stature_m

__all__ = ["FALL_STATES", "SEEN_S", "FallDetector", "FallEvent", "FallsConfig", "Household",
           "HouseholdMember", "Minutes", "PeopleFalls", "Sample", "Usual", "last_seen", "stature_m",
           "usual_absence", "watched_between"]
