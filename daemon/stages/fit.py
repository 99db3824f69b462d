"""Fitting stage: ``landmarks`` mailbox (LandmarkMsg) -> uDEAS fit -> ``fits`` mailbox (FitMsg).

Warm-up compiles (or loads from the numba cache) the fitting kernels before the stage reports ready. Video
mode: each frame starts from the previous one; the fitter is reset when the stream starts again (sequence
number going back) or after a gap of more than a second of capture time.
"""

from __future__ import annotations

from daemon import clock
from daemon.messages import FitMsg, origin
from daemon.stages.base import StageRuntime

RESET_GAP_S = 1.0


def run(rt: StageRuntime) -> None:
    from fitting import FitResult, Fitter

    with rt.step():
        fitter = Fitter(rt.config.fitting)
        fitter.warmup()
    rt.ready()
    inbox = rt.input
    failures = 0
    last: tuple[int, float] | None = None
    while True:
        rt.beat()
        rt.check_stop()
        msg = inbox.wait(0.1)
        if msg is None:
            continue
        frame = msg.frame
        with rt.step():
            t_in = clock.now()
            if last is not None and (frame.seq <= last[0] or msg.t_capture - last[1] > RESET_GAP_S):
                fitter.reset()
            last = (frame.seq, msg.t_capture)
            try:
                result = fitter.fit(frame.landmarks, frame.seq, msg.t_capture, msg.image_size, mode="video",
                                    intrinsics=msg.intrinsics, depth_m=frame.depth_m)
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
