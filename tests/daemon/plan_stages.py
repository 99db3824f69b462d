"""Stage entry points used only by the supervisor tests: real processes with trivial work, so the
supervision machinery (spawn, mailboxes, heartbeats, watchdog, restarts, shutdown) is tested on its own."""

from __future__ import annotations

import dataclasses
import os
import time

from posed.daemon import clock
from posed.daemon.stages.base import StageRuntime
from posed.daemon.stages.plan import StageSpec


def source(rt: StageRuntime) -> None:
    """Emits (seq, t_capture) at 50 Hz."""
    warm = float(os.environ.get("POSED_TEST_WARMUP_S", "0"))
    with rt.step():
        time.sleep(warm)
    rt.row.set_camera("open")
    rt.report(camera={"state": "open", "kind": "test"})
    rt.ready()
    seq = 0
    while True:
        rt.beat()
        rt.check_stop()
        t = clock.now()
        with rt.step():
            rt.send((seq, t))
        rt.done(0.0, t)
        seq += 1
        time.sleep(0.02)


def relay(rt: StageRuntime) -> None:
    rt.ready()
    while True:
        rt.beat()
        rt.check_stop()
        msg = rt.input.wait(0.1)
        if msg is None:
            continue
        with rt.step():
            t0 = clock.now()
            time.sleep(0.002)
            rt.send(msg)
        rt.done(clock.now() - t0, msg[1])


def sink(rt: StageRuntime) -> None:
    rt.ready()
    while True:
        rt.beat()
        rt.check_stop()
        msg = rt.input.wait(0.1)
        if msg is None:
            continue
        with rt.step():
            t0 = clock.now()
        rt.done(clock.now() - t0, msg[1])


def fatal(rt: StageRuntime) -> None:
    rt.fatal("the test model is missing", fix="run: posed models fetch")


PLAN = (
    StageSpec("capture", "tests.daemon.plan_stages:source", None, "frames"),
    StageSpec("landmarks", "tests.daemon.plan_stages:relay", "frames", "landmarks"),
    StageSpec("fitting", "tests.daemon.plan_stages:relay", "landmarks", "fits"),
    StageSpec("publisher", "tests.daemon.plan_stages:sink", "fits", None),
)
FATAL_PLAN = PLAN[:3] + (StageSpec("publisher", "tests.daemon.plan_stages:fatal", "fits", None),)


def fall_fits(rt: StageRuntime) -> None:
    """Feeds the publisher FitMsgs of a scripted fall (bench.falls_scenarios, perfect fits), without drops,
    then idles. Capture times are the scenario's time line from the start of the stage."""
    from posed.bench import falls_scenarios as scenarios
    from posed.daemon.messages import FitMsg
    from posed.landmarks import LandmarkFrame

    sc = next(s for s in scenarios.catalogue("tune") if s.name == FALL_SCENARIO)
    intrinsics = sc.camera.intrinsics
    rt.ready()
    t0 = clock.now()
    for fr in scenarios.frames(sc):
        result = scenarios.truth_result(fr, sc.camera)
        result = dataclasses.replace(result, t=t0 + fr.t)
        lms = LandmarkFrame(fr.seq, t0 + fr.t, fr.landmarks)
        while rt.output.pending():
            rt.beat()
            rt.check_stop()
            time.sleep(0.001)
        now = clock.now()
        rt.send(FitMsg(result, lms, t0 + fr.t, (sc.camera.width, sc.camera.height), (), intrinsics, now))
        rt.done(0.0, now)
        time.sleep(0.005)
    while True:
        rt.beat()
        rt.check_stop()
        time.sleep(0.05)


FALL_SCENARIO = "tune/fall/standing-forward/fast-v30"
FALL_OVERRIDES = ("falls.camera_tilt_deg=12", "falls.camera_height_m=1.0", "falls.alarm_after_s=3")
PUBLISHER_PLAN = (
    StageSpec("capture", "tests.daemon.plan_stages:fall_fits", None, "fits"),
    StageSpec("publisher", "posed.daemon.stages.publish:run", "fits", None),
)
# the web stage beside a stage of scripted fits, with no publisher: nobody on its bus (tests/viz/test_web_bus.py)
WEB_PLAN = (
    StageSpec("capture", "tests.daemon.plan_stages:fall_fits", None, "fits"),
    StageSpec("web", "posed.daemon.stages.web:run", None, None),
)
