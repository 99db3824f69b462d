"""A source URI with a query (``file:PATH?loop=true``, as ``--source`` gives it) reaches the stage plan and the
stages split: a looped landmark recording is still replayed directly (no camera or landmark stage)."""

from posed.daemon.config import load_config
from posed.daemon.preflight import check, resolve_source
from posed.daemon.stages.plan import default_plan


def _never(_):
    raise AssertionError("the demo input is not needed here")


def test_looped_landmark_recording_keeps_the_recording_plan(shared_data):
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    cfg = resolve_source(load_config(None, [f"source.path={rec}?loop=true&realtime=false"]), _never)
    assert cfg.source.path == str(rec) and cfg.source.loop and not cfg.source.realtime
    assert [s.name for s in default_plan(cfg)] == ["capture", "fitting", "publisher"]
    assert default_plan(cfg)[0].entry.endswith(":run_recording")
    assert check(cfg) == []


def test_a_bad_query_is_left_for_the_check_to_report(shared_data):
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    cfg = resolve_source(load_config(None, [f"source.path={rec}?lop=true"]), _never)
    assert "?" in cfg.source.path
    problems = check(cfg)
    assert any("lop" in p for p in problems), problems


def test_camera_faults_on_a_landmark_recording_are_a_problem_not_ignored(shared_data):
    """The fault keys act on camera frames (hal.faults); a landmark replay has none, and took them silently."""
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    cfg = resolve_source(load_config(None, [f"source.path={rec}?disconnect_at=40&disconnect_s=0"]), _never)
    assert cfg.source.fault_disconnect_at == 40
    problems = check(cfg)
    assert len(problems) == 1 and "a .landmarks.jsonl replay has none" in problems[0], problems
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    cfg = resolve_source(load_config(None, [f"source.path={video}?disconnect_at=40&disconnect_s=0"]), _never)
    assert not any("replay has none" in p for p in check(cfg))       # a video's frames take them
