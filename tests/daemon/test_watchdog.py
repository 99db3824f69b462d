"""The watchdog's verdicts and its restart policy (backoff, escalation) without processes."""

import math

from posed.daemon.proc.watchdog import RestartPolicy, verdict

NAN = math.nan


def v(**kw):
    args = dict(alive=True, exitcode=None, state="running", beat=100.0, step_started=NAN, started=90.0,
                now=100.5, stuck_after_s=5.0, startup_timeout_s=60.0)
    args.update(kw)
    return verdict(**args)


def test_verdicts():
    assert v().kind == "ok"
    assert v(alive=False, exitcode=-9).kind == "dead" and "-9" in v(alive=False, exitcode=-9).reason
    assert v(step_started=94.0).kind == "stuck"                  # busy 6.5 s > 5 s
    assert v(step_started=96.0).kind == "ok"
    assert v(beat=94.0).kind == "stuck"                           # idle without heartbeat (SIGSTOP)
    assert "pipeline.stuck_after_s" in v(beat=94.0).reason
    assert v(state="starting", beat=10.0, step_started=10.0, started=50.0).kind == "ok"   # warm-up may be slow
    s = v(state="starting", started=30.0)
    assert s.kind == "stuck" and "startup_timeout_s" in s.reason
    assert v(state="stopping", beat=0.0).kind == "ok"


def test_backoff_doubles_and_resets_after_window():
    p = RestartPolicy(max_restarts=5, window_s=60.0, backoff_base_s=0.5, backoff_max_s=3.0)
    delays = []
    for i in range(5):
        delays.append(p.delay("landmarks", 10.0 + i))
        p.record("landmarks", 10.0 + i)
    assert delays == [0.0, 0.5, 1.0, 2.0, 3.0]
    assert p.delay("fitting", 15.0) == 0.0                       # per stage
    assert p.delay("landmarks", 100.0) == 0.0                    # the window has passed


def test_escalates_on_more_than_max_restarts_in_window():
    p = RestartPolicy(max_restarts=5, window_s=60.0)
    for i, stage in enumerate(["capture", "landmarks", "fitting", "publisher", "capture"]):
        p.record(stage, 100.0 + i)
        assert not p.escalated(100.0 + i)
    p.record("landmarks", 105.0)
    assert p.escalated(105.0) and p.recent(105.0) == 6
    assert not p.escalated(161.0)                                # the first ones left the window
    assert p.total == 6
