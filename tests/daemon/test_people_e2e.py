"""Several people through the daemon (issue 36 item 1): a real clip where a second man walks in, replayed
through ``posed run``: from when he is found the landmarks topic carries ``people`` and the pose topic one
object per person per frame (the frame's seq, each with its ``person`` track id, the one followed longest first);
the real squat video (one person) has no ``people`` and no ``person`` anywhere, as before."""

from __future__ import annotations

from collections import defaultdict

import pytest

from tests.daemon.frame_sizes_util import run_to_end


@pytest.mark.timeout(300)
def test_two_real_people_get_a_pose_each(tmp_path, shared_data):
    clip = shared_data / "reference" / "multi_person" / "s2d_enter.mp4"
    run = run_to_end(tmp_path, f"file:{clip}", "source.realtime=false", "pipeline.target_fps=10")
    assert run.code == 0, run.stderr[-2000:]
    by_seq = defaultdict(list)
    for p in run.got["pose"]:
        by_seq[p["seq"]].append(p)
    pairs = [ps for ps in by_seq.values() if len(ps) >= 2]
    assert len(pairs) >= 10, {s: len(v) for s, v in by_seq.items()}
    for ps in pairs:
        persons = [p.get("person") for p in ps]
        assert None not in persons and len(set(persons)) == len(persons), persons
    ids = {p["person"] for ps in pairs for p in ps}
    assert len(ids) >= 2
    # the landmarks topic: from the first frame with two people on, every frame lists everyone by track id
    with_people = [f for f in run.got["landmarks"] if f.get("people")]
    assert with_people and max(len(f["people"]) for f in with_people) >= 2
    for f in with_people:
        ids_f = [q["id"] for q in f["people"]]
        assert len(set(ids_f)) == len(ids_f) and len(f["people"][0]["landmarks"]) == 33


@pytest.mark.timeout(300)
def test_one_real_person_has_no_person_field(tmp_path, shared_data):
    video = shared_data / "reference" / "tfjs_pose_squats" / "pose_squats.mp4"
    run = run_to_end(tmp_path, f"file:{video}", "source.realtime=false")
    assert run.code == 0, run.stderr[-2000:]
    assert run.got["pose"] and all("person" not in p for p in run.got["pose"])
    assert len({p["seq"] for p in run.got["pose"]}) == len(run.got["pose"])      # one object per frame
    # a video knows no intrinsics: fitted through the assumed lens (falls.camera_hfov_deg), no metres published
    ok = [p for p in run.got["pose"] if p["ok"]]
    assert ok and all(p["projection"] == "perspective" and p["lens"] == "assumed" and "root_cam_m" not in p
                      for p in ok)


@pytest.mark.timeout(300)
def test_a_visitors_fall_is_reported_as_theirs(tmp_path, shared_data):
    """A real fall (urfd_00) with a real bystander (urfd_16, a daily activity) beside the camera's axis, the
    bystander in view first (so the frame's own person, followed longest, is not the one who falls): replayed
    through ``posed run`` with the default config, the fall is reported for the faller's track id with where
    they were, and nothing for the bystander."""
    from dataclasses import replace as _replace

    from posed.bench import people_recordings as pr
    from posed.daemon.config import Config
    from posed.landmarks.recording import write_recording

    folder = shared_data / "falls" / "urfd_dev"
    h_own, f_own = pr._read(folder / "urfd_00_fall.landmarks.jsonl")
    f_own = [_replace(f, landmarks=None) if f.t < 0.5 else f for f in f_own]    # walks into view later
    header, frames, who = pr.compose((h_own, f_own), pr._read(folder / "urfd_16_adl.landmarks.jsonl"),
                                     Config().pipeline)
    rec = tmp_path / "visitor.landmarks.jsonl"
    write_recording(rec, header, frames)
    run = run_to_end(tmp_path, f"file:{rec}", "source.realtime=false")
    assert run.code == 0, run.stderr[-2000:]
    faller = {i for i, w in who.items() if w == "own"}
    bystander = {i for i, w in who.items() if w == "bystander"}
    assert run.got["pose"][0]["person"] in bystander          # the frame's own person is the bystander
    events = run.got["events/fall"]
    assert events and {e["state"] for e in events} & {"falling", "on_floor"}, events
    assert all(e["person"] in faller for e in events), [(e["state"], e.get("person")) for e in events]
    assert all(len(e["root_cam_m"]) == 3 and e["root_cam_m"][2] > 0 for e in events)
    assert all(e["geometry"]["lens"] == "given" for e in events)          # the recording's camera
    assert len({e["id"] for e in events}) == 1
