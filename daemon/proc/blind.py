"""Never silently blind: the supervisor's judgement of whether frames reach the first stage after capture.

A fall detector that sees nothing must say so. The daemon is **blind** when it is ready, its source is open
(streaming, not lost or opening: that is ``waiting_for_camera``), and no frame has been processed by the stage
that takes the capture stage's output (the landmark stage; the fitting stage for a landmark recording) for
:func:`blind_after_s` seconds; or when a recording ended before any of its frames was processed. The reason
comes from what the capture stage counted since the last processed frame (frames skipped as bad, read
timeouts, frames captured that the next stage did not take) and from the last problem it reported, with its
fix. :class:`BlindWatch` is fed the health board's counters every tick; it has no clock or board of its own
and is tested on plain numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

BLIND_AFTER_S = 3.0


def blind_after_s(target_fps: float) -> float:
    """Seconds without a processed frame after which the daemon is blind: 3 s, or 3 frame periods at the
    pipeline's rate when that is longer (``pipeline.target_fps`` below 1 Hz)."""
    return max(BLIND_AFTER_S, 3.0 / max(target_fps, 1e-3))


@dataclass(frozen=True)
class Counts:
    """The counters that tell why nothing gets through: the capture stage's frames sent, bad frames and errors
    (read timeouts), and the consumer stage's frames processed and errors."""

    captured: int = 0
    bad_frames: int = 0
    timeouts: int = 0
    processed: int = 0
    consumer_errors: int = 0


class BlindWatch:
    """``update`` once per supervisor tick; ``blind`` is None or {since_s, reason, fix}."""

    def __init__(self, consumer: str, after_s: float = BLIND_AFTER_S) -> None:
        self.consumer = consumer
        self.after_s = after_s
        self.processed_any = False
        self.blind: dict | None = None
        self._since: float | None = None      # when the last frame was processed (or watching began)
        self._at_progress = Counts()
        self._last_processed = -1

    def update(self, now: float, ready: bool, camera: str, counts: Counts, problem: dict | None) -> dict | None:
        """The blind verdict at ``now`` (monotonic seconds): ``camera`` is the capture stage's camera state
        (opening, open, lost, ended, paused), ``problem`` the capture stage's last {error, fix} or None. Never
        blind while ``paused`` for privacy: nothing is looked at on purpose, and the 3 s start again after it."""
        if counts.processed != self._last_processed:
            self._last_processed = counts.processed
            if counts.processed > 0:
                self.processed_any = True
            self._since = now
            self._at_progress = counts
        if not ready or camera in ("opening", "lost", "none", "paused") or self._since is None:
            self._since = now
            self._at_progress = counts
            self.blind = None
            return None
        if camera == "ended":
            self.blind = None if self.processed_any else self._verdict(now, counts, problem, ended=True)
            return self.blind
        if now - self._since < self.after_s:
            self.blind = None
            return None
        self.blind = self._verdict(now, counts, problem, ended=False)
        return self.blind

    def _verdict(self, now: float, c: Counts, problem: dict | None, ended: bool) -> dict:
        base = Counts() if ended else self._at_progress
        secs = now - (self._since if self._since is not None else now)
        bad = c.bad_frames - base.bad_frames if c.bad_frames >= base.bad_frames else c.bad_frames
        timeouts = c.timeouts - base.timeouts if c.timeouts >= base.timeouts else c.timeouts
        captured = c.captured - base.captured if c.captured >= base.captured else c.captured
        errors = c.consumer_errors - base.consumer_errors if c.consumer_errors >= base.consumer_errors \
            else c.consumer_errors
        error = (problem or {}).get("error") or ""
        fix = (problem or {}).get("fix") or ""
        if ended:
            head = "the recording ended and none of its frames reached the " + self.consumer + " stage"
        else:
            head = f"no frame has reached the {self.consumer} stage for {secs:.0f} s"
        if bad > 0:
            why = f"{bad} frame(s) were skipped as unusable" + (f": {error}" if error else "")
        elif captured > 0:
            why = (f"{captured} frame(s) were captured but the {self.consumer} stage processed none"
                   + (f" ({errors} error(s))" if errors else ""))
            fix = f"see the {self.consumer} stage's error lines in the log (journalctl -u posed -p err)"
        elif timeouts > 0:
            why = f"the source delivered no frame ({timeouts} read timeout(s))" + (f": {error}" if error else "")
        else:
            why = "the source delivered no frame" + (f": {error}" if error else "")
        if not fix:
            fix = "check the source (posed config check --source URI probes it)"
        return {"since_s": round(secs, 1), "reason": f"{head}: {why}", "fix": fix}
