"""What the newcomer search hides of a followed person (landmarks.blanking, landmarks.people): the body drawn
from the landmarks covers the limbs, the trunk and the head but not the empty space a spread arm leaves in the
landmark box; where someone was lost a moment ago beside a followed person, only that person's body stays
painted; and on a real-footage composite the woman hidden while a man walks in front of her is found again,
under the id she had, once she shows beside him."""

from __future__ import annotations

import numpy as np

from posed.landmarks.blanking import HEAD_RADIUS, LIMB_WIDTH, body_mask, torso_length
from posed.landmarks.people import _blanked, _reopened
from posed.landmarks.tracks import landmark_box


def spread_arms(scale: float = 1.0, dx: float = 0.0) -> np.ndarray:
    """(33, 5) landmarks of a person facing the camera with both arms straight out to the sides, pixels:
    shoulders at y 100, hips at y 200 (torso 100 px at scale 1), wrists 150 px out from the shoulders."""
    lms = np.full((33, 5), 1.0)
    pts = {0: (0, 60), 11: (30, 100), 12: (-30, 100), 13: (105, 100), 14: (-105, 100), 15: (180, 100),
           16: (-180, 100), 23: (20, 200), 24: (-20, 200), 25: (22, 290), 26: (-22, 290), 27: (24, 380),
           28: (-24, 380)}
    for i in range(1, 11):
        pts[i] = (((i % 2) * 2 - 1) * 8, 55)
    for i, j in ((17, 15), (19, 15), (21, 15), (18, 16), (20, 16), (22, 16), (29, 27), (31, 27), (30, 28),
                 (32, 28)):
        pts[i] = pts[j]
    for i, (x, y) in pts.items():
        lms[i, :2] = (300 + dx + x * scale, y * scale)
    return lms


def test_the_body_covers_limbs_trunk_and_head_not_the_space_under_a_spread_arm():
    lms = spread_arms()
    mask = body_mask((420, 640), lms)
    assert torso_length(lms) == 100.0
    for a, b in ((11, 13), (13, 15), (12, 14), (14, 16), (23, 25), (25, 27), (24, 26), (26, 28)):
        for s in np.linspace(0.0, 1.0, 11):
            x, y = np.round(lms[a, :2] * (1 - s) + lms[b, :2] * s).astype(int)
            assert mask[y, x], (a, b, s)
    assert mask[150, 300] and mask[55, 300]                      # trunk, face
    # a limb is drawn LIMB_WIDTH torso lengths wide: covered just inside half of it, not at twice it
    assert mask[100 + int(0.45 * LIMB_WIDTH * 100), 440] and not mask[100 + int(1.0 * LIMB_WIDTH * 100), 440]
    # the head disc: HEAD_RADIUS torso lengths around the face's landmarks (centre y 55.5)
    assert mask[int(55 - 0.9 * HEAD_RADIUS * 100), 300] and not mask[int(55 - 1.2 * HEAD_RADIUS * 100), 300]
    # under the spread right arm, inside the landmark box (x 120..480), nothing is the body
    assert not mask[250:380, 400:470].any()
    # twice the size: twice the widths
    big = body_mask((840, 1280), spread_arms(2.0, 300.0))
    assert big[200 + int(0.9 * LIMB_WIDTH * 100), 2 * 140 + 300 + 300]


def test_a_body_with_missing_landmarks_draws_what_it_can():
    lms = spread_arms()
    lms[[15, 16, 17, 18, 19, 20, 21, 22, 13], :2] = np.nan          # hands and the left elbow lost
    mask = body_mask((420, 640), lms)
    assert mask[150, 300] and not mask[100, 460]
    lms[11, :2] = np.nan                                            # no torso length: drawn at the minimum
    assert torso_length(lms) == 4.0 and body_mask((420, 640), lms)[300, 322]   # on the left shank


def test_where_someone_was_just_lost_only_the_followed_body_stays_painted():
    rng = np.random.default_rng(0)
    image = rng.integers(0, 255, (420, 640, 3), dtype=np.uint8)
    him = spread_arms()
    painted = _blanked(image.copy(), [landmark_box(him)])
    fill = painted[250, 300]
    assert (painted[300, 430] == fill).all()                        # under his arm: inside his box, painted
    lost = np.array([380.0, 150.0, 470.0, 390.0])                   # where she was last seen, under his arm
    opened = _reopened(painted.copy(), image, [him], [lost])
    assert (opened[300, 430] == image[300, 430]).all()              # shown again where he is not
    assert (opened[200:230, 300] == fill).all()                     # his body stays painted
    assert (opened[300, 200] == fill).all()                         # his box outside her box: still painted
    assert (_reopened(painted.copy(), image, [him], []) == painted).all()


def test_the_woman_hidden_while_he_walks_in_front_is_found_again_under_her_id(models_dir, shared_data):
    """bench.people_scenes ``cross_front`` with the man cut from pose2sim's cam01 (a development view): she is
    lost while his body covers her (frame 31); his landmark box, his arms spread, still covers her when she
    shows again beside him. By frame 38 she is followed again with the track id she had, her landmarks on her
    (median within 15 px of her published ones: her error alone is about 3 px, the man's body is 100+ px
    away), and his track is still on him."""
    from posed.bench import people_scenes as scenes
    from posed.bench.mocap_landmarks import BODY12_IDX
    from posed.landmarks.config import LandmarkConfig
    from posed.landmarks.people import MultiPoseLandmarker

    a, b = scenes.load_clips(shared_data, "cam01")
    scenario = next(s for s in scenes.SCENARIOS if s.name == "cross_front")
    frames, maps = scenes.compose(a, b, scenario, "ab")
    many = MultiPoseLandmarker(LandmarkConfig(max_people=3), models_dir)

    def median_px(lms: np.ndarray, truth: np.ndarray) -> float:
        return float(np.median(np.linalg.norm(lms[:, :2] - truth, axis=1)))

    her_id = his_id = None
    for k, image in enumerate(frames[:39]):
        r = many.process_full(image, k / 5.0, k)
        truth_a = scenes.truth_on_canvas(a, k, maps[k]["a"])
        truth_b = scenes.truth12_on_canvas(b, k, maps[k]["b"])
        on_her = [p.id for p in r.people if median_px(p.result.frame.landmarks, truth_a) < 15.0]
        on_him = [p.id for p in r.people if median_px(p.result.frame.landmarks[BODY12_IDX], truth_b) < 25.0]
        if k == 20:                                  # both in view, apart: who is who
            assert len(on_her) == 1 and len(on_him) == 1, (on_her, on_him)
            her_id, his_id = on_her[0], on_him[0]
        if k == 38:
            assert on_her == [her_id], (k, on_her, her_id, [p.id for p in r.people])
            assert on_him == [his_id], (k, on_him, his_id)
