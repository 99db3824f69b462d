"""The capture stage's side of a pause for privacy (docs/daemon.md, "Pausing for privacy").

The publisher's :class:`daemon.stages.privacy_keeper.PrivacyKeeper` hands its :class:`PrivacyOrder` (the pause
running, or none) to the capture stage through the ``privacy`` mailbox, at each change and again every
``REFORWARD_S`` (a capture stage restarted since has none). :class:`PauseGate` is what the capture loop asks
before each frame: it starts from the state directory's ``privacy.json`` (so a capture stage, or a whole daemon,
started during a pause never opens the camera before the first order arrives), takes the newest order, and ends
a pause by itself when its ``until_unix`` has passed on the wall clock, order or not. Transitions are logged
(``capture_paused``, ``capture_resumed``), never frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from posed.daemon.stages.privacy_file import Pause, paused_now

REFORWARD_S = 1.0       # the keeper hands its order to the capture stage again this often (seconds)


@dataclass(frozen=True)
class PrivacyOrder:
    """What the capture stage must do: ``pause`` None: watch; else read nothing until ``pause.until_unix``."""

    pause: Pause | None


class PauseGate:
    """``paused()`` before each frame: True while a pause runs. ``mailbox``: the ``privacy`` mailbox (None: only
    the file and the clock); ``wall``: the unix clock (seconds)."""

    def __init__(self, mailbox, state_dir: Path | None, log, wall: Callable[[], float] = time.time) -> None:
        self._mailbox = mailbox
        self._wall = wall
        self.log = log
        self.pause: Pause | None = paused_now(state_dir, wall()) if state_dir is not None else None
        self._said: bool | None = None

    def paused(self) -> bool:
        """Whether no frame may be looked at now (the newest order taken; a pause past its end is over)."""
        if self._mailbox is not None:
            order = self._mailbox.take()
            if order is not None:
                self.pause = order.pause
        if self.pause is not None and self.pause.until_unix <= self._wall():
            self.pause = None                       # ended by the clock, even if no order says so
        paused = self.pause is not None
        if paused != self._said:
            if paused:
                self.log.info("capture_paused", until_unix=round(self.pause.until_unix, 3), by=self.pause.by,
                              note="paused for privacy: no frame is looked at")
            elif self._said is not None:
                self.log.info("capture_resumed", note="the pause for privacy ended: watching again")
            self._said = paused
        return paused
