"""The blind verdict (daemon/proc/blind.py) on plain counters: when it starts, what it blames, and the fix."""

from __future__ import annotations

from posed.daemon.proc.blind import BlindWatch, Counts, blind_after_s

PROBLEM = {"error": "frames/f_012.jpg: cannot decode this image", "fix": "replace or delete the image named in the error"}


def test_not_blind_before_ready_while_waiting_for_a_camera_or_within_the_delay():
    w = BlindWatch("landmarks", 3.0)
    assert w.update(0.0, False, "open", Counts(), None) is None
    assert w.update(10.0, True, "lost", Counts(timeouts=50), None) is None        # waiting_for_camera's case
    assert w.update(10.1, True, "open", Counts(timeouts=50), None) is None
    assert w.update(12.9, True, "open", Counts(timeouts=60), None) is None        # 2.8 s: not yet
    b = w.update(13.2, True, "open", Counts(timeouts=61), None)
    assert b is not None and "no frame has reached the landmarks stage for 3 s" in b["reason"]
    assert "the source delivered no frame (11 read timeout(s))" in b["reason"], b


def test_skipped_frames_are_blamed_with_the_capture_stage_fix():
    w = BlindWatch("landmarks", 3.0)
    w.update(0.0, True, "open", Counts(captured=5, processed=5), None)
    b = w.update(4.0, True, "open", Counts(captured=5, bad_frames=20, processed=5), PROBLEM)
    assert "20 frame(s) were skipped as unusable: frames/f_012.jpg" in b["reason"]
    assert b["fix"] == PROBLEM["fix"] and b["since_s"] == 4.0
    assert w.update(4.5, True, "open", Counts(captured=6, bad_frames=20, processed=6), PROBLEM) is None
    assert w.blind is None and w.processed_any


def test_a_stage_that_fails_every_frame_is_blamed():
    w = BlindWatch("landmarks", 3.0)
    w.update(0.0, True, "open", Counts(), None)
    b = w.update(5.0, True, "open", Counts(captured=40, consumer_errors=40), None)
    assert "40 frame(s) were captured but the landmarks stage processed none (40 error(s))" in b["reason"]
    assert "landmarks stage's error lines" in b["fix"]


def test_a_recording_that_ended_unprocessed_is_blind_at_once_one_that_was_processed_is_not():
    w = BlindWatch("fitting", 3.0)
    w.update(0.0, True, "open", Counts(), None)
    b = w.update(0.5, True, "ended", Counts(bad_frames=3), PROBLEM)
    assert b["reason"].startswith("the recording ended and none of its frames reached the fitting stage")
    w2 = BlindWatch("landmarks", 3.0)
    w2.update(0.0, True, "open", Counts(captured=1, processed=1), None)
    assert w2.update(30.0, True, "ended", Counts(captured=1, processed=1), None) is None


def test_the_delay_follows_a_slow_target_rate():
    assert blind_after_s(10.0) == 3.0 and blind_after_s(0.5) == 6.0
