"""The camera's pose put by the robot on ``posed/ROBOT/camera/mount``: the parser (every reason to reject, the
bounds), the samples in force at a capture time against a plain reference, and the publisher's feed (the clock,
the counters, the rate-limited log, the hand-over to the fitting stage)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from posed.daemon.bus.camera_mount import (
    MAX_PAYLOAD_BYTES,
    BadMount,
    CameraMount,
    parse_camera_mount,
)
from posed.daemon.stages.fit import frame_gravity
from posed.daemon.stages.mount_feed import MountFeed
from posed.daemon.stages.mount_samples import MAX_SAMPLES, MountSample, MountSamples, in_force
from posed.falls.features import gravity_from_tilt
from posed.landmarks import LandmarkFrame


def _json(**fields) -> bytes:
    return json.dumps(fields).encode()


# ------------------------------------------------------------------ the parser

def test_a_full_message_and_its_defaults():
    m = parse_camera_mount(_json(format="posed.camera_mount", version=1, time_unix=1.7e9, height_m=1.2,
                                 down=[0.0, 2.0, 0.0], valid_s=0.5, source=" tf:a->b ", future_field={"x": 1}))
    assert m == CameraMount((0.0, 1.0, 0.0), 1.2, 1.7e9, 0.5, "tf:a->b")
    m = parse_camera_mount(_json(tilt_deg=30.0, roll_deg=-4))          # format, version, time, height: optional
    assert m.time_unix is None and m.height_m is None and m.valid_s == 1.0 and m.source is None
    assert np.allclose(m.down, gravity_from_tilt(30.0, -4.0))
    assert parse_camera_mount('{"down": [1, 0, 0], "source": ""}') == CameraMount((1.0, 0.0, 0.0))


@pytest.mark.parametrize("payload,says", [
    (b"x" * (MAX_PAYLOAD_BYTES + 1), "more than 4096"),
    (b"\xff\xfe", "not UTF-8"),
    (b"{not json", "not JSON"),
    (b"[" * 100_00 + b"]" * 100_00, "more than 4096"),
    (b"[" * 4000, "not JSON"),
    (b"[0, 1, 0]", "not an object"),
    (b'"down"', "not an object"),
    (_json(format="posed.pose", down=[0, 1, 0]), "is not 'posed.camera_mount'"),
    (_json(version=2, down=[0, 1, 0]), "version 2 is newer than this posed reads (1)"),
    (_json(version=0, down=[0, 1, 0]), "version 0 is not 1"),
    (_json(version="1", down=[0, 1, 0]), "must be the integer 1"),
    (_json(version=True, down=[0, 1, 0]), "must be the integer 1"),
    (_json(height_m=1.0), "no gravity"),
    (_json(tilt_deg=10.0), '"tilt_deg" without "roll_deg"'),
    (_json(roll_deg=10.0), '"roll_deg" without "tilt_deg"'),
    (_json(down=[0, 1, 0], tilt_deg=1.0, roll_deg=0.0), "not both"),
    (_json(down=[0, 1, 0], roll_deg=0.0), "not both"),
    (_json(down=[0, 1]), "three numbers"),
    (_json(down="down"), "three numbers"),
    (_json(down={"x": 0}), "three numbers"),
    (_json(down=[0, "1", 0]), "numbers only"),
    (_json(down=[0, True, 0]), "numbers only"),
    (_json(down=[0, None, 0]), "numbers only"),
    (b'{"down": [0, NaN, 0]}', "finite"),
    (b'{"down": [0, Infinity, 0]}', "finite"),
    (b'{"down": [0, 1e999, 0]}', "finite"),
    (b'{"down": [0, 1' + b"0" * 400 + b', 0]}', "finite"),
    (_json(down=[0, 0, 0]), "not be all 0"),
    (_json(down=[1e-12, 0, 0]), "not be all 0"),
    (_json(tilt_deg=90.5, roll_deg=0), '"tilt_deg" 90.5 deg is out of range -90..90'),
    (_json(tilt_deg=0, roll_deg=-91), '"roll_deg" -91 deg is out of range -90..90'),
    (_json(tilt_deg="10", roll_deg=0), '"tilt_deg" must be a number'),
    (b'{"tilt_deg": NaN, "roll_deg": 0}', "finite"),
    (_json(down=[0, 1, 0], height_m=0.04), "out of range 0.05..5"),
    (_json(down=[0, 1, 0], height_m=5.01), "out of range 0.05..5"),
    (_json(down=[0, 1, 0], height_m=False), '"height_m" must be a number'),
    (b'{"down": [0, 1, 0], "height_m": -Infinity}', "finite"),
    (_json(down=[0, 1, 0], valid_s=0.04), "out of range 0.05..3600"),
    (_json(down=[0, 1, 0], valid_s=3601), "out of range 0.05..3600"),
    (_json(down=[0, 1, 0], time_unix=-1.0), '"time_unix" -1 s is out of range'),
    (_json(down=[0, 1, 0], time_unix=0), '"time_unix" must be Unix seconds after 1970'),
    (_json(down=[0, 1, 0], height_m=None), '"height_m" must be a number'),
    (_json(down=[0, 1, 0], valid_s=None), '"valid_s" must be a number'),
    (_json(down=[0, 1, 0], source=None), '"source" must be text'),
    (_json(down=[0, 1, 0], time_unix="now"), '"time_unix" must be a number'),
    (_json(down=[0, 1, 0], source=42), '"source" must be text'),
    (_json(down=[0, 1, 0], source="x" * 129), "too long (at most 128)"),
    (_json(down=[0, 1, 0], source="a\nb"), "control characters"),
])
def test_what_is_rejected_and_the_message_says_why(payload, says):
    with pytest.raises(BadMount) as err:
        parse_camera_mount(payload)
    text = str(err.value)
    assert says in text, text
    assert isinstance(err.value, ValueError) and "\n" not in text and len(text) < 600


@pytest.mark.parametrize("fields", [dict(height_m=0.05), dict(height_m=5.0), dict(valid_s=0.05), dict(valid_s=3600),
                                    dict(time_unix=1e-3)])
def test_the_bounds_are_inclusive(fields):
    parse_camera_mount(_json(down=[0, 1, 0], **fields))
    parse_camera_mount(_json(tilt_deg=-90, roll_deg=90))


def test_every_shape_of_junk_is_a_bad_mount_never_another_error():
    rng = np.random.default_rng(3)
    for _ in range(3000):
        with pytest.raises(BadMount):
            parse_camera_mount(rng.bytes(int(rng.integers(0, 200))).replace(b"{", b"["))
    values = [None, True, 0, -1, 1e308, "x", [], {}, [0, 1], [0, 1, 0], [[0], 1, 0], {"down": 1}]
    for key in ("down", "tilt_deg", "roll_deg", "height_m", "valid_s", "time_unix", "source", "format", "version"):
        for v in values:
            try:
                parse_camera_mount(json.dumps({"down": [0, 1, 0], key: v}))
            except BadMount:
                pass


# ------------------------------------------------------------------ the sample in force at a capture time

def _reference(samples: list[MountSample], t: float) -> MountSample | None:
    """Plainly: the latest sample taken at or before t (the last received among equal times), if it holds at t."""
    latest = None
    for s in samples:                   # in order received
        if s.t <= t and (latest is None or s.t >= latest.t):
            latest = s
    return latest if latest is not None and t <= latest.t + latest.valid_s else None


def test_the_sample_in_force_matches_a_plain_reference():
    rng = np.random.default_rng(11)
    for trial in range(300):
        received: list[MountSample] = []
        box = MountSamples()
        for i in range(int(rng.integers(0, 20))):
            t = float(np.round(rng.uniform(0.0, 10.0), 1))      # out of order, repeated times
            s = MountSample(t, float(rng.choice([0.05, 0.3, 1.0, 5.0])), (0.0, 1.0, 0.0), None, f"s{trial}-{i}")
            received.append(s)
            box = box.add(s)
        assert [s.t for s in box.samples] == sorted(s.t for s in received)
        assert box.received == len(received)
        for t in np.round(rng.uniform(-1.0, 16.0, 40), 2).tolist() + [s.t for s in received] + \
                [s.t + s.valid_s for s in received]:
            assert box.at(t) is _reference(received, t), (trial, t)
            assert in_force(box.samples, t) is box.at(t)


def test_a_newer_sample_supersedes_an_older_one_that_claimed_longer():
    long = MountSample(0.0, 3600.0, (0.0, 1.0, 0.0), None, "mast")
    short = MountSample(10.0, 0.5, (0.0, 0.9, 0.4), None, "head")
    box = MountSamples().add(long).add(short)
    assert box.at(5.0) is long and box.at(10.2) is short
    assert box.at(11.0) is None                       # the head moved since the mast's: nothing holds
    assert box.at(-0.1) is None                       # before every sample


def test_the_samples_are_bounded_the_oldest_dropped():
    box = MountSamples()
    for i in range(3 * MAX_SAMPLES):
        box = box.add(MountSample(float(i), 1.0, (0.0, 1.0, 0.0)))
    assert len(box.samples) == MAX_SAMPLES and box.received == 3 * MAX_SAMPLES
    assert box.samples[0].t == 2 * MAX_SAMPLES and box.newest.t == 3 * MAX_SAMPLES - 1
    late = box.add(MountSample(0.5, 1.0, (0.0, 1.0, 0.0)))     # older than all kept: dropped at once
    assert late.samples == box.samples and late.received == box.received + 1


# ------------------------------------------------------------------ the publisher's feed

class _Log:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str, dict]] = []

    def _add(self, level, event, **kw):
        self.lines.append((level, event, kw))

    def info(self, event, **kw):
        self._add("info", event, **kw)

    def warning(self, event, **kw):
        self._add("warning", event, **kw)

    def error(self, event, **kw):
        self._add("error", event, **kw)


class _Box:
    def __init__(self) -> None:
        self.put_values: list = []

    def put(self, value) -> bool:
        self.put_values.append(value)
        return False


def test_the_feed_dates_counts_forwards_and_logs_on_change_only():
    now = [100.0]
    log, box = _Log(), _Box()
    feed = MountFeed(log, box, now=lambda: now[0], from_wall=lambda u: u - 1_000_000.0)
    feed.on_payload(_json(down=[0, 1, 0], source="tf"))                             # no time: when received
    feed.on_payload(_json(down=[0, 1, 0.1], time_unix=1_000_100.2, source="tf"))      # on the daemon's clock
    assert [s.t for s in feed.samples.samples] == pytest.approx([100.0, 100.2])
    assert box.put_values[-1] == feed.samples and feed.received == 2
    puts = len(box.put_values)
    feed.reforward(200.0)
    feed.reforward(200.5)                                  # handed again once a second (a restarted fitting stage)
    feed.reforward(201.0)
    assert len(box.put_values) == puts + 2 and box.put_values[-1] == feed.samples
    feed.on_payload(_json(down=[0, 1, 0], time_unix=1_000_102.0))               # 2 s ahead of this clock
    feed.on_payload(b"junk")
    assert feed.rejected == 2 and "not JSON" in feed.last_error and feed.received == 2
    assert feed.at(100.1).t == 100.0 and feed.at(100.3).t == pytest.approx(100.2) and feed.at(102.0) is None
    st = feed.status(now=100.5)
    assert st == {"received": 2, "rejected": 2, "late": 0, "last_error": feed.last_error,
                  "age_s": pytest.approx(0.3), "in_force": False, "source": "tf"}
    for _ in range(1000):
        feed.on_payload(b"\x00")
        feed.on_payload(_json(down=[0, 1, 0], source="tf"))
    assert feed.at(100.5) is not None and feed.at(100.6) is not None      # in force again: said once
    events = [e for _, e, _ in log.lines]
    assert feed.rejected == 1002
    assert events.count("bad_camera_mount") == 5                   # rate-limited: 5 a minute
    assert events.count("camera_mount_received") == 1 and events.count("camera_mount_in_force") == 2
    assert events.count("camera_mount_not_in_force") == 1 and "camera_mount_source_changed" not in events
    assert len(feed.samples.samples) == MAX_SAMPLES


def test_the_fit_takes_the_robots_down_first():
    frame = LandmarkFrame(0, 0.0, None, gravity=(0.0, 9.8, 0.0))
    robot = np.array(gravity_from_tilt(30.0))
    assert np.allclose(frame_gravity(frame, None, robot=robot), robot)
    assert np.allclose(frame_gravity(frame, None), [0.0, 9.8, 0.0])               # no robot: the IMU, as before
    assert math.isclose(float(np.linalg.norm(frame_gravity(frame, None, robot=robot))), 1.0)


def test_the_parser_agrees_with_the_shipped_schema():
    """What the daemon accepts is what client/schemas/camera_mount.json calls valid (beyond it, the daemon bounds
    ``source`` to 128 characters and the payload to 4 kB: the schema says nothing of either)."""
    from posed.client import contract

    rng = np.random.default_rng(5)
    choices = {"down": [[0, 1, 0], [0.1, 9.8, 2], [0, 0, 0], [0, 1], [0, "1", 0], [0, True, 0], None, "x"],
               "tilt_deg": [0, 35.5, -90, 90, 90.5, "1", None], "roll_deg": [0, -3, 91, None],
               "height_m": [0.05, 1.2, 5, 0.0, 6, None, "1"], "valid_s": [0.05, 1, 3600, 0, 4000, None],
               "time_unix": [1.7e9, 1e-3, 0, -5, "now", None], "source": ["tf", "", 3, None],
               "format": ["posed.camera_mount", "posed.ack"], "version": [1, 2, 0, "1"]}
    for _ in range(3000):
        msg = {k: v[int(rng.integers(len(v)))] for k, v in choices.items() if rng.random() < 0.5}
        try:
            parse_camera_mount(json.dumps(msg))
            accepted = True
        except BadMount:
            accepted = False
        assert accepted == (contract.errors(msg, "camera_mount") == []), msg


def test_poses_from_a_clock_behind_this_one_are_said_late_never_used_silently():
    """The robot's computer 3 s behind this one: every pose has run out (valid_s 0.5) when it arrives. Kept, never
    in force, counted as late and said with the fix (rate-limited), not taken for a rejected message."""
    now = [500.0]
    log = _Log()
    feed = MountFeed(log, None, now=lambda: now[0], from_wall=lambda u: u - 1_000_000.0)
    for k in range(100):
        now[0] = 500.0 + 0.1 * k
        feed.on_payload(_json(down=[0, 1, 0], time_unix=1_000_000.0 + now[0] - 3.0, valid_s=0.5))
    assert feed.received == 100 and feed.late == 100 and feed.rejected == 0
    assert feed.at(now[0]) is None and feed.status()["late"] == 100
    said = [kw for _, e, kw in log.lines if e == "camera_mount_late"]
    assert len(said) == 5 and said[0]["arrived_after_s"] == pytest.approx(3.0) and "NTP" in said[0]["fix"]
    feed.on_payload(_json(down=[0, 1, 0], time_unix=1_000_000.0 + now[0] - 0.2, valid_s=0.5))   # in sync again
    assert feed.late == 100 and feed.at(now[0]) is not None
