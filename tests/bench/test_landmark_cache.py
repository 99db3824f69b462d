"""bench.landmark_cache: the cached recordings' tag follows the landmark stage's code."""

from __future__ import annotations

from posed.bench import landmark_cache as LC


def test_the_tag_changes_with_the_stage_code_and_only_then(tmp_path, monkeypatch):
    tag = LC.stage_tag()
    assert len(tag) == 10 and int(tag, 16) >= 0 and LC.stage_tag() == tag      # the real stage: stable
    (tmp_path / "a.py").write_text("x = 1\n")
    monkeypatch.setattr(LC, "LANDMARKS_SOURCE", tmp_path)
    first = LC.stage_tag()
    assert first != tag and LC.stage_tag() == first
    (tmp_path / "notes.txt").write_text("not code")                            # only the Python files count
    assert LC.stage_tag() == first
    (tmp_path / "a.py").write_text("x = 2\n")
    assert LC.stage_tag() != first
