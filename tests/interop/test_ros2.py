"""ROS 2 through rmw_zenoh, checked against an implementation nobody here wrote: ``zenoh-ros2-sdk`` (PyPI), a
Python implementation of rmw_zenoh's wire protocol. Its subscribers — on the key expressions and type hashes
it computes itself (its own REP-2016 hashing, from the .msg definitions) — receive and decode the JointState,
MarkerArray, PointStamped and DiagnosticArray that a running ``posed run`` publishes while replaying a real
fall, through a router on 127.0.0.1; its ``ros2 topic list``/``info`` equivalents find posed's publishers from
their liveliness tokens; its attachment parser reads posed's attachments. The key expressions and tokens are
also checked against the rules of rmw_zenoh's design document (docs/ros2.md)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

# zenoh-ros2-sdk: a test dependency (pyproject's test extra)
from zenoh_ros2_sdk import message_registry
from zenoh_ros2_sdk.attachment import Attachment
from zenoh_ros2_sdk.discovery import get_topic_info, get_topic_names_and_types
from zenoh_ros2_sdk.entity import EndpointEntity, EntityKind, NodeEntity
from zenoh_ros2_sdk.keyexpr import endpoint_liveliness_keyexpr, node_liveliness_keyexpr, topic_keyexpr
from zenoh_ros2_sdk.session import ZenohSession
from zenoh_ros2_sdk.utils import get_type_hash, load_dependencies_recursive

from posed.daemon.bus import ros2
from posed.daemon.bus import ros2_messages as rm
from tests.daemon.zenoh_util import client, free_port, router
from tests.interop.daemons import ROOT, URFD, Daemon, fall_overrides, wait_for

HEX64 = r"[0-9a-f]{64}"


def write_msg_files(root) -> None:
    """The .msg definitions of the four types and their dependencies, laid out as a ROS share folder
    (<pkg>/msg/<Name>.msg) for the SDK, which otherwise downloads them."""
    for ros_type in rm.TYPES:
        text = rm.msg_definition(ros_type)
        sections = re.split(r"\n=+\nMSG: ", text)
        named = [(ros_type, sections[0])] + [tuple(s.split("\n", 1)) for s in sections[1:]]
        for name, body in named:
            pkg, *_, msg = name.split("/")
            path = root / pkg / "msg" / f"{msg}.msg"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body.strip() + "\n")


@pytest.fixture(scope="module")
def msg_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("ros_share")
    write_msg_files(root)
    message_registry._registry = None
    message_registry.get_registry(str(root))
    return root


@pytest.mark.parametrize("ros_type", rm.TYPES)
def test_type_hashes_agree_with_the_sdk(msg_dir, ros_type):
    """The SDK computes REP-2016 hashes with its own code (hashlib over its own type description); rosbags
    (which posed uses) agrees for each type posed publishes."""
    registry = message_registry.get_registry()
    definition = registry.get_msg_file_path(ros_type).read_text()
    deps = load_dependencies_recursive(ros_type, definition, registry)
    assert get_type_hash(ros_type, msg_definition=definition, dependencies=deps) == rm.type_hash(ros_type)
    assert re.fullmatch(f"RIHS01_{HEX64}", rm.type_hash(ros_type))
    assert rm.type_hash(ros_type, "humble") == "TypeHashNotSupported"


def test_keys_tokens_and_attachment_follow_rmw_zenoh():
    """Against the design document's rules and the SDK's own builders for the same entities."""
    key = ros2.topic_key(3, "/robot1/posed/joint_states", rm.JOINT_STATE)
    assert re.fullmatch(rf"3/robot1/posed/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_{HEX64}", key)
    assert key == topic_keyexpr(3, "/robot1/posed/joint_states", "sensor_msgs::msg::dds_::JointState_",
                                rm.type_hash(rm.JOINT_STATE))
    zid = "8b20917502ee955ac4476e0266340d5c"
    node = NodeEntity(domain_id=3, session_id=zid, node_id=0, node_name="posed", namespace="/robot1")
    assert ros2.node_token(3, zid, "/robot1", "posed") == node_liveliness_keyexpr(node) == \
        f"@ros2_lv/3/{zid}/0/0/NN/%/%robot1/posed"
    ep = EndpointEntity(node=node, entity_id=2, kind=EntityKind.PUBLISHER, name="/robot1/posed/skeleton",
                        dds_type_name=rm.dds_type_name(rm.MARKER_ARRAY), type_hash=rm.type_hash(rm.MARKER_ARRAY),
                        qos=ros2.QOS_DEFAULT)
    token = ros2.publisher_token(3, zid, "/robot1", "posed", 2, "/robot1/posed/skeleton", rm.MARKER_ARRAY)
    assert token == endpoint_liveliness_keyexpr(ep)
    assert token == (f"@ros2_lv/3/{zid}/0/2/MP/%/%robot1/posed/%robot1%posed%skeleton/"
                     f"visualization_msgs::msg::dds_::MarkerArray_/{rm.type_hash(rm.MARKER_ARRAY)}/::,10:,:,:,,")
    # no namespace: '%'; the topic keeps its leading slash, mangled
    assert ros2.node_token(0, zid, "", "posed") == f"@ros2_lv/0/{zid}/0/0/NN/%/%/posed"
    assert ros2.fully_qualified("", "posed/joint_states") == "/posed/joint_states"
    assert ros2.fully_qualified("/r1", "/abs") == "/abs"
    gid = bytes(range(16))
    att = ros2.attachment(7, 1_700_000_000_123_456_789, gid)
    assert len(att) == 33 and att == Attachment(7, 1_700_000_000_123_456_789, gid).to_bytes()
    back = Attachment.from_bytes(att)
    assert (back.sequence_id, back.timestamp_ns, back.gid) == (7, 1_700_000_000_123_456_789, gid)


class Received:
    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.by_type: dict[str, list] = {t: [] for t in rm.TYPES}
        self.poses: list[dict] = []
        self.attachments: dict[str, list[Attachment]] = {}
        self.encodings: set[str] = set()

    def add(self, ros_type: str, msg) -> None:
        with self.lock:
            self.by_type[ros_type].append(msg)


@pytest.fixture(scope="module")
def ros_run(tmp_path_factory, shared_data, msg_dir):
    """A router; ``posed run`` with ros2 enabled (domain 7, namespace /home) replaying the real fall clip; the
    SDK's subscribers, a plain zenoh subscriber for posed's JSON poses and the raw ROS samples."""
    from zenoh_ros2_sdk import ROS2Subscriber

    port = free_port()
    rep = f"tcp/127.0.0.1:{port}"
    r = router(rep)
    got = Received()
    d = Daemon(tmp_path_factory.mktemp("ros2"), "ros1", shared_data / URFD / "urfd_02_fall.landmarks.jsonl", rep,
               *fall_overrides(shared_data), "source.loop=true", "source.realtime=true", "ros2.enabled=true",
               "ros2.domain_id=7", "ros2.namespace=/home", "pipeline.status_period_s=0.5")
    old = ZenohSession._instance
    ZenohSession._instance = None
    subs = []
    try:
        with client(rep) as s:
            def raw(sample):
                k = str(sample.key_expr)
                with got.lock:
                    got.encodings.add(str(sample.encoding))
                    got.attachments.setdefault(k, []).append(Attachment.from_bytes(sample.attachment.to_bytes()))

            def pose(sample):
                with got.lock:
                    got.poses.append(json.loads(sample.payload.to_string()))

            keep = [s.declare_subscriber("7/**", raw), s.declare_subscriber("posed/ros1/pose", pose)]
            for ros_type, topic in ((rm.JOINT_STATE, "/home/posed/joint_states"),
                                    (rm.MARKER_ARRAY, "/home/posed/skeleton"),
                                    (rm.POINT_STAMPED, "/home/posed/person_position"),
                                    (rm.DIAGNOSTIC_ARRAY, "/home/posed/fall_events")):
                subs.append(ROS2Subscriber(topic, ros_type, lambda m, t=ros_type: got.add(t, m), domain_id=7,
                                           router_ip="127.0.0.1", router_port=port, node_name="checker"))
            d.start()
            wait_for(lambda: all(len(v) >= 5 for t, v in got.by_type.items() if t != rm.DIAGNOSTIC_ARRAY)
                     and got.by_type[rm.DIAGNOSTIC_ARRAY], 180, "ROS 2 messages of every type", d)
            # what `ros2 topic list` / `ros2 topic info -v` would say (the SDK's versions; asked again until the
            # liveliness query has gone round the router and brought posed's publishers back: a query answered
            # within its 1 s timeout by the checker's own subscribers only is a partial answer on a loaded machine)
            def topic_list():
                got_topics = get_topic_names_and_types(domain_id=7, router_ip="127.0.0.1", router_port=port,
                                                       timeout=1.0)
                names = {name for name, _ in got_topics or ()}
                return got_topics if {"/home/posed/joint_states", "/home/posed/skeleton"} <= names else None

            def topic_info():
                got_info = get_topic_info("/home/posed/skeleton", domain_id=7, router_ip="127.0.0.1",
                                          router_port=port, timeout=1.0, verbose=True)
                return got_info if got_info and got_info.publisher_count > 0 else None

            topics = wait_for(topic_list, 20, "topic list naming posed's topics")
            info = wait_for(topic_info, 20, "topic info with posed's publisher")
            with got.lock:
                snapshot = {t: list(v) for t, v in got.by_type.items()}
                poses, atts, encodings = list(got.poses), dict(got.attachments), set(got.encodings)
            del keep
        yield {"port": port, "msgs": snapshot, "poses": poses, "attachments": atts, "encodings": encodings, "topics": topics,
               "info": info, "subscribers": subs}
    finally:
        for sub in subs:
            try:
                sub.close()
            except Exception:
                pass
        if ZenohSession._instance is not None:
            ZenohSession._instance.session.close()
        ZenohSession._instance = old
        d.stop()
        r.close()


def test_the_sdk_subscribers_got_each_type_on_their_own_keys(ros_run):
    for sub in ros_run["subscribers"]:
        assert sub.type_hash == rm.type_hash(sub.msg_type)     # the SDK computed it; it matched posed's key
    assert {t: len(v) > 0 for t, v in ros_run["msgs"].items()} == dict.fromkeys(rm.TYPES, True)


def test_joint_states_are_the_poses_joint_angles_in_radians(ros_run):
    by_stamp = {round(p["time_unix"], 3): p for p in ros_run["poses"] if p.get("ok")}
    matched = knees = 0
    for js in ros_run["msgs"][rm.JOINT_STATE]:
        t = js.header.stamp.sec + js.header.stamp.nanosec * 1e-9
        pose = by_stamp.get(round(t, 3))
        if pose is None:
            continue
        matched += 1
        # the joint angles this frame measured, by URDF-style names; the rest (the clip has no elbows, the
        # model's fixed angles) left out
        measured = [n for n in pose["joint_angles_deg"] if n in pose["measured"]["angles"]]
        assert list(js.name) == [rm.URDF_JOINT_NAMES[n] for n in measured]
        assert not {"left_elbow_joint", "head_pitch_joint"} & set(js.name)
        knees += "left_knee_joint" in js.name
        np.testing.assert_allclose(js.position, np.radians([pose["joint_angles_deg"][n] for n in measured]),
                                   atol=1e-12)
    assert matched >= 5 and knees >= 1


def test_skeleton_and_position_are_in_the_camera_frame(ros_run):
    by_stamp = {round(p["time_unix"], 3): p for p in ros_run["poses"] if p.get("ok")}
    matched = 0
    for ma in ros_run["msgs"][rm.MARKER_ARRAY]:
        m = ma.markers[0]
        if m.action == 3:                       # DELETEALL: the person was lost
            continue
        pose = by_stamp.get(round(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, 3))
        if pose is None:
            continue
        matched += 1
        assert m.header.frame_id == "camera_color_optical_frame"   # the clip has intrinsics: position known
        bones, joints = ma.markers
        seen = [k for k in pose["joints_3d"] if k in pose["measured"]["joints_3d"]]   # no elbows in this clip
        assert "left_elbow" not in seen and "left_knee" in seen
        assert (bones.type, joints.type) == (5, 7)
        assert len(bones.points) == 2 * sum(a in seen and b in seen for a, b in rm.BONES)
        root = np.array(pose["root_cam_m"])
        got = np.array([[p.x, p.y, p.z] for p in joints.points])
        want = np.array([pose["joints_3d"][k] for k in seen]) + root
        np.testing.assert_allclose(got, want, atol=1e-9)
    assert matched >= 5
    for ps in ros_run["msgs"][rm.POINT_STAMPED]:
        assert ps.header.frame_id == "camera_color_optical_frame" and 0.5 < ps.point.z < 10.0   # metres ahead


def test_fall_events_are_diagnostics(ros_run):
    d = ros_run["msgs"][rm.DIAGNOSTIC_ARRAY][0]
    [status] = d.status
    values = {kv.key: kv.value for kv in status.values}
    assert status.name == "posed/fall" and status.hardware_id == "ros1"
    assert values["state"] in ("falling", "on_floor", "alarm", "recovered") and len(values["id"]) == 32
    assert status.level == rm.DIAGNOSTIC_LEVEL[values["state"]] and status.message == f"fall {values['state']}"
    assert math.isfinite(float(values["time_unix"])) and "pelvis" in values["features"]


def test_attachments_and_discovery(ros_run):
    atts = ros_run["attachments"]
    assert set(atts) == {ros2.topic_key(7, f"/home/posed/{t}", ty) for t, ty in (
        ("joint_states", rm.JOINT_STATE), ("skeleton", rm.MARKER_ARRAY), ("person_position", rm.POINT_STAMPED),
        ("fall_events", rm.DIAGNOSTIC_ARRAY))}
    now_ns = time.time_ns()
    for seq in atts.values():
        assert len({a.gid for a in seq}) == 1 and len(seq[0].gid) == 16
        nums = [a.sequence_id for a in seq]
        assert nums == sorted(nums) and len(set(nums)) == len(nums) and nums[0] >= 1
        assert all(0 < now_ns - a.timestamp_ns < 600e9 for a in seq)
    assert ros_run["encodings"] == {"application/cdr"}
    topics = dict(ros_run["topics"])
    assert topics["/home/posed/joint_states"] == [rm.JOINT_STATE]
    assert topics["/home/posed/skeleton"] == [rm.MARKER_ARRAY]
    info = ros_run["info"]
    assert info.publisher_count == 1 and info.publishers[0].node_name == "posed"
    assert info.publishers[0].node_namespace == "/home"


def test_the_example_of_ros2_md_runs(ros_run):
    """The documented subscriber, as written, with the fixture's router, domain (ROS_DOMAIN_ID) and namespace."""
    doc = (ROOT / "docs" / "ros2.md").read_text()
    code = re.findall(r"```python\n(.*?)```", doc, re.S)[0]
    code = code.replace("router_port=7447", f"router_port={ros_run['port']}").replace(
        '"/posed/joint_states"', '"/home/posed/joint_states"')
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         env={**os.environ, "ROS_DOMAIN_ID": "7"})
    assert out.returncode == 0, out.stderr[-2000:]
    lines = [x for x in out.stdout.splitlines() if x.strip()]
    assert len(lines) >= 5, out.stdout[-2000:] + out.stderr[-2000:]
    sec, _, angles = lines[-1].partition(" ")
    assert int(sec) > 1.6e9 and re.search(r"'(left|right)_\w+_joint': ", angles) and "theta" not in angles


def test_a_fall_diagnostic_says_whose_fall_when_several_people_are_watched():
    event = {"id": "a" * 32, "robot": "r1", "state": "on_floor", "confidence": 0.8, "time_unix": 1.7e9,
             "features": ["pelvis_at_floor_level"]}
    plain = {kv.key: kv.value for kv in rm.fall_diagnostic(event, "posed").status[0].values}
    assert "person" not in plain and "member" not in plain            # one person: as before
    theirs = rm.fall_diagnostic({**event, "person": 3, "member": "Grandma"}, "posed")
    values = {kv.key: kv.value for kv in theirs.status[0].values}
    assert values["person"] == "3" and values["member"] == "Grandma" and values["state"] == "on_floor"
