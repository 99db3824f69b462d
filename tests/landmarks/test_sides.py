"""Left and right kept apart (landmarks.sides): a label flip faster than anyone can turn is put back; a turn a
person can make never is; on real video (Sports2D's demo, where BlazePose flips the man on the block for four
frames while he faces the camera) his left shoulder stays on his left."""

from __future__ import annotations

import math

import numpy as np
import pytest

from posed.landmarks import LandmarkFrame, PersonLandmarks, RecordingHeader
from posed.landmarks import sides as S
from posed.landmarks.config import LandmarkConfig
from posed.landmarks.pipeline import PoseLandmarker
from tests.daemon.frame_sizes_util import read_frames

TORSO_PX = 200.0


def _body(heading: float, cx: float = 500.0, tilt: float = 0.0) -> np.ndarray:
    """33 landmarks (x, y, z, visibility, presence) of a torso ``TORSO_PX`` long turned by ``heading`` radians
    about its long axis (0: facing the camera), the axis tilted by ``tilt`` radians in the image; limbs hang
    below the shoulders and hips. The shoulders and hips are exactly as wide as the anthropometric ones."""
    lms = np.zeros((33, 5))
    lms[:, 3:] = 1.0
    up = np.array([math.sin(tilt), -math.cos(tilt)])          # hip -> shoulder, image y down
    across = np.array([-up[1], up[0]])                        # the torso's normal in the image
    hip = np.array([cx, 600.0])
    shoulder = hip + TORSO_PX * up
    for (left, right), centre, rel in (((11, 12), shoulder, S.SHOULDER_WIDTH_REL),
                                       ((23, 24), hip, S.HIP_WIDTH_REL)):
        half = 0.5 * rel * TORSO_PX * math.cos(heading)
        lms[left, :2] = centre + half * across
        lms[right, :2] = centre - half * across
    for i in range(33):
        if i not in (11, 12, 23, 24):
            side = 11 if i % 2 else 12
            lms[i, :2] = lms[side, :2] - 0.3 * TORSO_PX * up + np.array([0.0, i])
    return lms


def test_a_left_right_swap_between_two_frames_is_a_flip():
    a = _body(0.0)
    assert S.labels_flipped(a[S.MIRROR], a, 0.1)
    assert not S.labels_flipped(a, a, 0.1)
    # the same whatever the torso's tilt in the image (a person lying on the floor)
    lying = _body(0.0, tilt=math.pi / 2)
    assert S.labels_flipped(lying[S.MIRROR], lying, 0.1)


@pytest.mark.parametrize("tilt", [0.0, 0.6, math.pi / 2])
def test_no_turn_a_person_can_make_is_taken_for_a_flip(tilt):
    """Turning at 95 % of TURN_RATE_MAX, sampled at 10 and 30 fps from every starting heading, never fires;
    at twice the rate the front-to-back frames do."""
    for fps in (10.0, 30.0):
        dt = 1.0 / fps
        for start in np.linspace(0.0, 2 * math.pi, 37):
            slow = [_body(start + 0.95 * S.TURN_RATE_MAX * dt * k, tilt=tilt) for k in range(12)]
            assert not any(S.labels_flipped(b, a, dt) for a, b in zip(slow, slow[1:], strict=False)), (fps, start)
    dt = 0.1
    fast = [_body(2.0 * S.TURN_RATE_MAX * dt * k, tilt=tilt) for k in range(12)]
    assert any(S.labels_flipped(b, a, dt) for a, b in zip(fast, fast[1:], strict=False))


def test_a_person_bent_towards_the_camera_turning_fast_is_not_taken_for_a_flip():
    """Bent forward towards the camera, the torso looks half as long and the shoulders twice as wide for it; a
    turn at 300 deg/s through the side view then looks impossible against the anthropometric width — but
    the keeper remembers the torso's length from two seconds of standing upright, and does not fire."""
    def bent(heading: float) -> np.ndarray:
        lms = _body(heading)
        hip = 0.5 * (lms[23, :2] + lms[24, :2])
        lms[:, 1] = hip[1] + 0.5 * (lms[:, 1] - hip[1])        # the torso foreshortened to half its length
        return lms
    dt, rate = 0.1, math.radians(300.0)
    headings = [math.radians(65.0) + rate * dt * k for k in range(8)]      # through 90 deg: the side view
    frames = [bent(h) for h in headings]
    assert any(S.labels_flipped(b, a, dt) for a, b in zip(frames, frames[1:], strict=False))  # without memory
    keeper = S.SideKeeper()
    world = np.zeros((33, 3))
    for k in range(20):                                          # two seconds upright, facing the camera
        keeper.check(k * dt, _body(math.radians(60.0)), world)
    swapped = [keeper.check(2.0 + k * dt, lms, world)[2] for k, lms in enumerate(frames)]
    assert not any(swapped), swapped


def test_a_torso_pitching_through_the_line_of_sight_is_not_taken_for_a_flip():
    """Bending over towards a camera above (picking something up; urfd_30_adl in shared/data/falls, MediaPipe's
    labels right throughout), the shoulders drop past the hips in the image: the torso's own image axis
    shrinks and turns round while the shoulders' left-right offset stays. Measured across each frame's own
    axis the offset changes sign with no turn; across the longer torso's axis it does not, and the keeper
    leaves the labels alone. A real flip while so bent is still found."""
    def pitched(k: int) -> np.ndarray:
        lms = _body(0.0)
        hip = 0.5 * (lms[23, :2] + lms[24, :2])
        lms[:, 1] = hip[1] + (1.0 - 0.3 * k) * (lms[:, 1] - hip[1])    # 1.0, 0.7, ... -0.8 of its length
        lms[[11, 12], 1] += np.array([-4.0, 4.0])                      # a little roll, as on real video
        return lms
    frames = [pitched(k) for k in range(7)]
    own = [S.signed_widths(f[:, :2])[0] for f in frames]
    assert own[0] > 0 > own[-1]                                        # each frame's own axis: the sign flips
    keeper = S.SideKeeper()
    for k in range(10):                                                # settled: a second upright
        keeper.check(k / 10.0, _body(0.0), None)
    for k, f in enumerate(frames):
        if k:
            assert not S.labels_flipped(f, frames[k - 1], 0.1), k
        _, _, swapped = keeper.check(1.0 + k / 10.0, f, None)
        assert not swapped, k
    assert S.labels_flipped(frames[-1][S.MIRROR], frames[-2], 0.1)


def test_hips_that_clearly_kept_their_side_veto_a_shoulder_flip():
    a = _body(0.0)
    b = a.copy()
    b[[11, 12]] = a[[12, 11]]                 # only the shoulders swapped
    assert not S.labels_flipped(b, a, 0.1)
    b[[23, 24]] = a[[24, 23]]
    assert S.labels_flipped(b, a, 0.1)


def test_missing_torso_landmarks_or_no_time_decide_nothing():
    a = _body(0.0)
    b = a[S.MIRROR].copy()
    assert not S.labels_flipped(b, a, 0.0)
    b[11, :2] = np.nan
    assert not S.labels_flipped(b, a, 0.1)


def _stream(flipped: set[int], n: int = 30, fps: float = 10.0):
    """n frames of one person facing the camera at ``fps``, the labels swapped on the frames in ``flipped``;
    world landmarks carry each landmark's index so their order can be checked."""
    for k in range(n):
        lms = _body(0.0, cx=400.0 + 3.0 * k)
        world = np.tile(np.arange(33.0)[:, None], (1, 3))
        if k in flipped:
            lms, world = lms[S.MIRROR], world[S.MIRROR]
        yield k / fps, lms, world


def test_a_short_flip_after_settled_labels_is_put_back_with_the_world_landmarks():
    keeper = S.SideKeeper()
    flips = {10, 11, 12}
    for k, (t, lms, world) in enumerate(_stream(flips)):
        out, w, swapped = keeper.check(t, lms, world)
        assert swapped == (k in flips), k
        assert out[11, 0] > out[12, 0], k          # facing the camera: the left shoulder on the image right
        np.testing.assert_array_equal(w[:, 0], np.arange(33.0))


def test_the_hips_flickering_across_does_not_unsettle_the_labels():
    """A side view's hips, nearly on top of each other, swap sides now and then in the model's output; the
    labels stay settled, and a shoulder flip right after is still put back."""
    keeper = S.SideKeeper()
    for k, (t, lms, world) in enumerate(_stream({12})):
        if k in (9, 10):
            lms = lms.copy()
            lms[[23, 24]] = lms[[24, 23]]              # the hips only, as in a side view
        swapped = keeper.check(t, lms, world)[2]
        assert swapped == (k == 12), k


def test_labels_that_had_not_settled_are_taken_as_they_come():
    keeper = S.SideKeeper()
    swapped = [keeper.check(t, lms, w)[2] for t, lms, w in _stream({0, 1})]    # the track's first frames
    assert not any(swapped)


def test_a_flip_that_lasts_is_accepted_and_a_gap_forgets():
    keeper = S.SideKeeper()
    long_flip = set(range(10, 30))
    out = [keeper.check(t, lms, w)[2] for t, lms, w in _stream(long_flip)]
    n_put_back = sum(out)
    assert 0 < n_put_back <= round(S.PERSIST_S * 10.0) + 1
    assert not any(out[10 + n_put_back:])
    keeper = S.SideKeeper()
    for t, lms, w in _stream(set(), n=10):
        keeper.check(t, lms, w)
    t, lms, w = next(_stream({0}, n=1))
    assert not keeper.check(0.9 + S.MAX_GAP_S + 0.05, lms, w)[2]      # too long since the last frame


def test_reset_forgets_the_person():
    keeper = S.SideKeeper()
    for t, lms, w in _stream(set(), n=10):
        keeper.check(t, lms, w)
    keeper.reset()
    t, lms, w = next(_stream({0}, n=1))
    assert not keeper.check(1.0, lms, w)[2]


def _frames(flipped: set[int], people: bool, n: int = 30):
    """LandmarkFrames of ``_stream``, each with its depth (33 distinct values) mirrored with the labels; with
    ``people``, the person (track 7) beside a second one (track 3) whose labels never flip."""
    for k, (t, lms, world) in enumerate(_stream(flipped, n)):
        world = np.column_stack([world, np.ones((33, 2))])
        depth = 2.0 + np.arange(33.0) / 100.0
        depth = depth[S.MIRROR] if k in flipped else depth
        crowd = None
        if people:
            other = _body(0.0, cx=1200.0)
            crowd = (PersonLandmarks(3, other), PersonLandmarks(7, lms, world=world, depth_m=depth))
        yield LandmarkFrame(k, t, lms, world=world, depth_m=depth, people=crowd)


@pytest.mark.parametrize("people", [False, True])
def test_a_recording_has_every_persons_labels_put_back_with_their_world_landmarks_and_depth(people):
    """What posed fit, posed falls and the daemon's replay do to a recording another tool made: the frame's
    own person and, with ``people``, each track by its own keeper; image and world landmarks and the depth at
    them swapped back together; a frame without anyone forgets the person."""
    sides = S.RecordingSides()
    flips = {10, 11, 12}
    for k, frame in enumerate(_frames(flips, people)):
        out = sides(frame)
        assert out.landmarks[11, 0] > out.landmarks[12, 0], k       # facing the camera: left on the image right
        np.testing.assert_array_equal(out.world[:, 0], np.arange(33.0))
        np.testing.assert_array_equal(out.depth_m, 2.0 + np.arange(33.0) / 100.0)
        if people:
            own = next(p for p in out.people if p.id == 7)
            np.testing.assert_array_equal(own.landmarks, out.landmarks)
            np.testing.assert_array_equal(own.world, out.world)
            np.testing.assert_array_equal(own.depth_m, out.depth_m)
            assert next(p for p in out.people if p.id == 3) == frame.people[0]     # never flipped: untouched
        if k not in flips:
            assert out is frame
    assert sides.frames_put_back == len(flips)
    empty = LandmarkFrame(30, 3.0, None)
    assert sides(empty) is empty
    assert sides.frames_put_back == len(flips)


def test_a_recording_is_checked_unless_its_extractor_kept_the_sides_or_the_config_says_not_to():
    plain = RecordingHeader((1280, 720), 10.0, "MediaPipe")
    kept = RecordingHeader((1280, 720), 10.0, "posed landmarks", extra={"sides_kept": True})
    assert S.RecordingSides.needed(plain, True)
    assert not S.RecordingSides.needed(plain, False)
    assert not S.RecordingSides.needed(kept, True)


def test_real_video_the_man_facing_the_camera_keeps_his_left_on_his_left(models_dir, shared_data):
    """Sports2D's demo (30 fps): the man on the block faces the camera throughout; BlazePose full takes his
    left for his right on frames 67-71 (seen: docs/benchmarks.md). With the sides kept his left shoulder stays
    on the image's right on every frame of 55-75; with MediaPipe's labels as they come it does not."""
    frames = read_frames(shared_data / "reference" / "multi_person" / "s2d_enter.mp4", 76)
    facing = {}
    for keep in (True, False):
        lm = PoseLandmarker(LandmarkConfig(keep_sides=keep), models_dir)
        facing[keep] = []
        for k, image in enumerate(frames):
            r = lm.process(image, k / 30.0, k)
            if k >= 55:
                assert r.landmarks is not None, k
                facing[keep].append(float(S.signed_widths(r.landmarks[:, :2])[0]))
    assert min(facing[True]) > 0.0, facing[True]
    assert min(facing[False]) < 0.0, facing[False]
