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
