"""posed tells a carer when it stops watching and when it watches again (``hooks.on_watch_lost``): the audit
found that a camera unplugged, blind or ended for hours reached nobody — fall hooks run only on falls.

The judgement on status objects (pure), a real hook program (stdin, environment, retries), and the real
daemon on the real squat video unplugged for 5 s (the HAL's fault injection)."""

from __future__ import annotations

import json
from pathlib import Path

from posed.daemon.config.sections import HookConfig, HooksConfig
from posed.daemon.logs import get
from posed.daemon.outbox.watch_hooks import WatchHooks, WatchLoss, WatchNotice, why_not_watching
from tests.daemon.replay_util import replay_to_end

SQUAT = "reference/tfjs_pose_squats/pose_squats.mp4"

# one line per run: watch, attempt, reason, then the stdin JSON; fails its first run when REC.fail exists
HOOK = """\
rec="$1"
body=$(cat)
echo "$POSED_WATCH|$POSED_HOOK_ATTEMPT|$POSED_ROBOT|$POSED_WATCH_SINCE_UNIX|$POSED_WATCH_REASON|$body" >> "$rec"
if [ -e "$rec.fail" ]; then rm "$rec.fail"; exit 3; fi
"""


def _status(state: str, camera: str = "open", **extra) -> dict:
    return {"state": state, "camera": {"state": camera, **extra.pop("cam", {})}, **extra}


def test_lost_after_the_delay_once_and_back_once():
    w = WatchLoss("r1", after_s=60.0)
    blind = _status("blind", blind={"reason": "no frame for 4 s"})
    assert w.update(_status("running"), 0.0, 1000.0) is None
    assert w.update(blind, 10.0, 1010.0) is None                       # not yet: a routine hiccup
    assert w.update(_status("starting"), 40.0, 1040.0) is None         # undecided: the clock keeps running
    lost = w.update(blind, 70.0, 1070.0)
    assert isinstance(lost, WatchNotice) and not lost.watching and lost.since_unix == 1010.0
    assert lost.reason == "blind: no frame for 4 s" and lost.to_json()["not_watching_s"] == 60.0
    assert w.update(blind, 80.0, 1080.0) is None and w.lost                # said once
    assert w.update(_status("running"), 90.0, 1090.0) is None and w.lost   # back once steady for the delay
    back = w.update(_status("running"), 150.0, 1150.0)
    assert back is not None and back.watching and back.since_unix == 1010.0 and not w.lost
    assert w.update(_status("running"), 160.0, 1160.0) is None
    # a short loss that ends before the delay says nothing, either way
    assert w.update(_status("waiting_for_camera"), 170.0, 1170.0) is None
    assert w.update(_status("running"), 180.0, 1180.0) is None
    assert w.update(_status("running"), 250.0, 1250.0) is None


def _flap(w: WatchLoss, lost_s: float, back_s: float, seconds: float) -> list[WatchNotice]:
    """Status objects once a second from a camera lost ``lost_s`` then back ``back_s``, over and over."""
    out, t = [], 0
    while t < seconds:
        gone = t % (lost_s + back_s) < lost_s
        status = _status("waiting_for_camera", camera="lost") if gone else _status("running")
        if (notice := w.update(status, float(t), 1000.0 + t)) is not None:
            out.append(notice)
        t += 1
    return out


def test_a_camera_lost_half_the_time_is_said_once():
    """Lost 50 s of every 100 s: before, never said (each loss shorter than the 60 s delay)."""
    notices = _flap(WatchLoss("r1", after_s=60.0), 50, 50, 3600)
    assert [n.watching for n in notices] == [False]
    assert notices[0].time_unix == 1110.0 and notices[0].since_unix == 1000.0     # 60 s not watching in all


def test_a_flapping_camera_is_one_loss_not_a_storm_of_hooks():
    """Lost 70 s, back 10 s, for an hour, then steady: before, a lost and a back every 80 s (90 notices)."""
    w = WatchLoss("r1", after_s=60.0)
    notices = _flap(w, 70, 10, 3600)
    assert [n.watching for n in notices] == [False]
    steady = [w.update(_status("running"), 3600.0 + t, 4600.0 + t) for t in range(0, 61)]
    assert [n.watching for n in steady if n is not None] == [True]


def test_hiccups_far_apart_call_nobody():
    """A 5 s stage restart every 2 minutes: never 60 s not watching within a loss."""
    assert _flap(WatchLoss("r1", after_s=60.0), 5, 115, 3600) == []


def test_why_names_the_state_and_the_camera():
    assert why_not_watching(_status("running")) is None
    assert why_not_watching(_status("stopping")) == ""
    assert why_not_watching(_status("running", camera="ended")) == "camera ended"
    assert why_not_watching(_status("waiting_for_camera", camera="lost", cam={"error": "unplugged"})) == \
        "waiting_for_camera: unplugged"
    assert why_not_watching(_status("escalated")) == "escalated"


def _hooks(tmp_path: Path, retries: int = 0) -> tuple[HooksConfig, Path]:
    script, rec = tmp_path / "hook.sh", tmp_path / "rec"
    script.write_text(HOOK)
    cfg = HooksConfig(on_watch_lost=(HookConfig(argv=("/bin/sh", str(script), str(rec)), timeout_s=10.0,
                                                retries=retries),), retry_delay_s=0.1)
    return cfg, rec


def _lines(rec: Path) -> list[list[str]]:
    return [line.split("|", 5) for line in rec.read_text().splitlines()] if rec.exists() else []


def test_a_real_hook_gets_the_notice_and_is_retried(tmp_path):
    cfg, rec = _hooks(tmp_path, retries=1)
    Path(f"{rec}.fail").touch()
    runner = WatchHooks(cfg, get("test"))
    notice = WatchNotice(False, "r9", "camera lost: unplugged", 1000.0, 1060.5)
    runner.submit(notice)
    runner.submit(WatchNotice(True, "r9", "camera lost: unplugged", 1000.0, 1100.0))
    runner.close(timeout=10.0)
    lines = _lines(rec)
    assert [(x[0], x[1]) for x in lines] == [("lost", "1"), ("lost", "2"), ("back", "1")], lines
    watch, _, robot, since, reason, body = lines[0]
    assert (robot, since, reason) == ("r9", "1000.0", "camera lost: unplugged")
    assert json.loads(body) == notice.to_json() and json.loads(body)["not_watching_s"] == 60.5


def test_the_daemon_says_an_unplugged_camera_and_its_return(tmp_path, shared_data):
    cfg, rec = _hooks(tmp_path)
    hook = cfg.on_watch_lost[0]
    source = f"{shared_data / SQUAT}?disconnect_at=10&disconnect_s=5"
    replay_to_end(tmp_path, source, "watchbot", ("status",), "pipeline.target_fps=30",
                  f'hooks.on_watch_lost=[{{argv: [{", ".join(hook.argv)}], timeout_s: 10}}]',
                  "hooks.watch_lost_after_s=1.5", "source.realtime=true", timeout_s=90.0)
    # paced (5 fps): the 11 s of video after the return are watched steadily for longer than the delay, so
    # "back" comes before the recording ends (an ended recording is not watching)
    lines = _lines(rec)
    assert [x[0] for x in lines[:2]] == ["lost", "back"], lines
    lost, back = json.loads(lines[0][5]), json.loads(lines[1][5])
    assert lost["robot"] == "watchbot" and ("camera" in lost["reason"] or "waiting_for_camera" in lost["reason"])
    assert lost["not_watching_s"] >= 1.5 and back["since_unix"] == lost["since_unix"]
    assert back["not_watching_s"] < 15.0                          # the unplug lasted 5 s
