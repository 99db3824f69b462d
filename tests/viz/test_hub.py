"""The live view's hub: poses thinned to the configured rate on the receiving clock, NaN never sent as a
number, unobserved angles sent as null, each event message passed on once, the last minute kept."""

from __future__ import annotations

import json
import math

from posed.falls import FallEvent
from posed.fitting import FitResult
from posed.viz.web.hub import WINDOW_S, Hub


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def pose(seq: int, t_unix: float, knee: float = 30.0, **extra) -> FitResult:
    return FitResult(seq, seq * 0.1, True, joint_angles_deg={"theta_kn_l": knee, "theta_el_l": 12.0},
                     joints_3d={"mid_hip": (0.0, 0.0, 0.0), "left_knee": (0.1, 0.4, math.nan)},
                     extra={"time_unix": t_unix, **extra})


def test_poses_are_thinned_to_the_rate_and_json_clean():
    clock = Clock()
    hub = Hub("r", pose_rate_hz=10.0, clock=clock)
    q = hub.subscribe()
    for i in range(30):            # 30 poses over 1 s at 30 Hz
        clock.now = i / 30.0
        hub.on_pose("r", pose(i, 1000.0 + i / 30.0, unobserved=["theta_el_l"]))
    sent = []
    while not q.empty():
        sent.append(q.get())
    assert 9 <= len(sent) <= 11
    msg = sent[0]
    json.dumps(msg, allow_nan=False)                      # NaN became null
    assert msg["joints"]["left_knee"][2] is None
    assert msg["angles"]["theta_kn_l"] == 30.0 and msg["angles"]["theta_el_l"] is None
    assert msg["evidence"] == ""                          # the fit did not say what it used


def test_a_pose_says_what_its_3d_came_from():
    """Issue 38 item 5: the page names the fit's evidence, and an assumed lens."""
    hub = Hub("r", pose_rate_hz=10.0, clock=Clock())
    q = hub.subscribe()
    hub.on_pose("r", pose(1, 1000.0, evidence=["landmarks", "world"], lens="assumed"))
    assert q.get()["evidence"] == "3D from: 2D landmarks + BlazePose 3D, assumed lens"


def test_events_pass_once_and_the_snapshot_keeps_one_minute():
    clock = Clock()
    hub = Hub("r", pose_rate_hz=60.0, clock=clock)
    q = hub.subscribe()
    ev = FallEvent(id="e1", robot="r", state="falling", t_onset=1.0, t_impact=1.5, t_detect=2.0, confidence=0.8)
    for _ in range(3):             # the daemon republishes until acknowledged
        hub.on_event("r", ev)
    assert [m["type"] for m in iter(lambda: None if q.empty() else q.get(), None)] == ["event"]
    for i in range(200):
        clock.now = float(i)
        hub.on_pose("r", pose(i, 1000.0 + i))
    snap = hub.snapshot()
    times = [a["time_unix"] for a in snap["angles"]]
    assert times[-1] == 1199.0 and times[0] >= 1199.0 - WINDOW_S
    assert snap["events"][0]["id"] == "e1" and snap["labels"]["theta_kn_l"] == "left knee flexion"
    hub.on_acked("e1", True)
    assert hub.snapshot()["acked"] == ["e1"]


def test_a_slow_page_loses_its_oldest_messages_not_the_others():
    hub = Hub("r", pose_rate_hz=60.0, clock=Clock())
    slow, fast = hub.subscribe(), hub.subscribe()
    for i in range(400):
        hub.on_alive(i % 2 == 0)
        fast.get()
    assert slow.qsize() == slow.maxsize and fast.qsize() == 0
    assert slow.get()["alive"] == (((400 - slow.maxsize) % 2) == 0)   # the newest ones are kept


def drawn_knees(q) -> list:
    """The left knee of every pose message waiting in a page's queue."""
    out = []
    while not q.empty():
        m = q.get()
        if m["type"] == "pose":
            out.append(m["angles"]["theta_kn_l"])
    return out


def test_with_several_people_the_page_draws_one_person():
    """Each frame's poses (the frame's own person first, then the others, same seq): the page gets the frame's
    own person only; once the status says the household member is followed, that person only."""
    from posed.client.types import Status

    clock = Clock()
    hub = Hub("r", pose_rate_hz=1000.0, clock=clock)
    q = hub.subscribe()
    for seq in range(5):
        clock.now = seq * 0.1
        hub.on_pose("r", pose(seq, 1000.0 + seq, knee=10.0, person=1))      # the frame's own (a visitor)
        hub.on_pose("r", pose(seq, 1000.0 + seq, knee=80.0, person=2))      # the other
    assert drawn_knees(q) == [10.0] * 5
    hub.on_status("r", Status("r", "running", 1001.0, 10.0, 20.0, 0, 0, "open", 0,
                              raw={"falls": {"household": {"followed": 2}}}))
    for seq in range(5, 10):
        clock.now = seq * 0.1
        hub.on_pose("r", pose(seq, 1000.0 + seq, knee=10.0, person=1))
        hub.on_pose("r", pose(seq, 1000.0 + seq, knee=80.0, person=2))
    assert drawn_knees(q) == [80.0] * 5
    clock.now = 2.0
    hub.on_pose("r", pose(11, 1011.0, knee=33.0))           # one person again (no ids): drawn
    assert hub.snapshot()["pose"]["angles"]["theta_kn_l"] == 33.0


def test_the_camera_says_when_it_watches_by_infrared():
    """A RealSense in a dark room (status camera.spectrum infrared) is said on the page's camera line."""
    from posed.client.types import Status

    hub = Hub("r", clock=Clock())
    q = hub.subscribe()
    for spectrum, said in (("infrared", "open (dark: by infrared)"), ("colour", "open"), (None, "open")):
        camera = {"state": "open"} if spectrum is None else {"state": "open", "spectrum": spectrum}
        hub.on_status("r", Status("r", "running", 1001.0, 10.0, 20.0, 0, 0, "open", 0, raw={"camera": camera}))
        statuses = []
        while not q.empty():
            m = q.get()
            if m["type"] == "status":
                statuses.append(m)
        assert statuses and statuses[-1]["camera"] == said
