"""Fitting stage: ``landmarks`` mailbox (LandmarkMsg) -> uDEAS fit -> ``fits`` mailbox (FitMsg).

Warm-up compiles (or loads from the numba cache) the fitting kernels before the stage reports ready. Video
mode: each frame starts from the previous one; the fitter is reset when the stream starts again (sequence
number going back) or after a gap of more than a second of capture time. Frames without a person
(``landmarks`` None) are passed on as ``ok: false`` results, like any other: the fall detector's timers and
its "lost after a descent" rule need them. :class:`StreamFit` is that per-frame logic, shared with the
offline ``posed falls``.
"""

from __future__ import annotations

from posed.daemon import clock
from posed.daemon.messages import FitMsg, origin
from posed.daemon.stages.base import StageRuntime

RESET_GAP_S = 1.0


class StreamFit:
    """The fit as this stage runs it: video mode, reset when the stream restarts or after a gap."""

    def __init__(self, fitter) -> None:
        self.fitter = fitter
        self.last: tuple[int, float] | None = None

    def fit(self, frame, t_capture: float, image_size, intrinsics):
        """Fit one LandmarkFrame (``landmarks`` None: no person, an ``ok: false`` result)."""
        if self.last is not None and (frame.seq <= self.last[0] or t_capture - self.last[1] > RESET_GAP_S):
            self.fitter.reset()
        self.last = (frame.seq, t_capture)
        return self.fitter.fit(frame.landmarks, frame.seq, t_capture, image_size, mode="video",
                               intrinsics=intrinsics, depth_m=frame.depth_m, world=frame.world)


def run(rt: StageRuntime) -> None:
    from posed.fitting import CalibrationError, FitResult, Fitter

    with rt.step():
        try:
            fitter = Fitter(rt.config.fitting)
        except CalibrationError as exc:          # checked before start; the file changed since: restarting
            rt.fatal(f"fitting.calibration: {exc}", fix="fix or remove fitting.calibration")   # cannot cure it
        fitter.warmup()
    rt.ready()
    inbox = rt.input
    failures = 0
    stream = StreamFit(fitter)
    while True:
        rt.beat()
        rt.check_stop()
        msg = inbox.wait(0.1)
        if msg is None:
            continue
        frame = msg.frame
        with rt.step():
            t_in = clock.now()
            try:
                result = stream.fit(frame, msg.t_capture, msg.image_size, msg.intrinsics)
            except Exception as exc:  # the fitter should never raise; if it does, keep the pipeline going
                failures += 1
                rt.error()
                if failures <= 3 or failures % 100 == 0:
                    rt.log.error("fit_failed", error=repr(exc), seq=frame.seq, failures=failures)
                fitter.reset()
                result = FitResult.failure(frame.seq, msg.t_capture, f"fit failed: {exc!r}")
            t_out = clock.now()
            rt.send(FitMsg(result, frame, msg.t_capture, msg.image_size,
                           msg.stamps + (("fitting_in", t_in), ("fitting_out", t_out)), msg.intrinsics,
                           msg.t_origin), lossless=msg.t_origin is not None)
        rt.done(t_out - t_in, origin(msg), t_out)
