"""ROS 2 robots see posed through rmw_zenoh (ROS 2's Zenoh middleware; docs/ros2.md): the publisher stage's one
Zenoh session also carries standard ROS 2 messages (:mod:`daemon.bus.ros2_messages`) the way an rmw_zenoh
publisher does, so ``ros2 topic echo``, RViz and any node on the same Zenoh network (the ROS router
``rmw_zenohd``, joined with ``zenoh.connect``) receive them without posed's code.

What rmw_zenoh (Jazzy) expects, and what this module does (sources: ros2/rmw_zenoh docs/design.md as relayed to
this project, and the independent Python implementation ``zenoh-ros2-sdk``, whose wire format matches):

* data key ``<domain_id>/<fully qualified topic without the leading />/<DDS type name>/<type hash>``, e.g.
  ``0/posed/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e…``; the payload is CDR with its
  encapsulation header (rosbags);
* an attachment on every sample: int64 sequence number (from 1, per publisher), int64 source timestamp (ns
  since the Unix epoch), then the publisher's 16-byte GID preceded by its length (one byte) — 33 bytes, written
  with Zenoh's own serializer (``zenoh.ext.z_serialize``);
* liveliness tokens for discovery (``ros2 node list``, ``ros2 topic list``/``info``): the node
  ``@ros2_lv/<domain>/<zid>/<node_id>/<node_id>/NN/<enclave>/<namespace>/<node>`` and each publisher
  ``@ros2_lv/<domain>/<zid>/<node_id>/<entity_id>/MP/<enclave>/<namespace>/<node>/<mangled topic>/<type>/<hash>/<qos>``
  where mangling turns every ``/`` into ``%`` and an empty enclave or namespace is ``%``; ``<qos>`` is the
  compact QoS of a default reliable, volatile, keep-last-10 publisher, ``::,10:,:,:,,``.

Humble: its rmw_zenoh puts ``TypeHashNotSupported`` where the hash goes (``ros2.distro: humble``); the rest is
assumed the same (not verified against a Humble install). Publishing never raises into the pipeline: a message
that cannot be built or sent is counted and logged (the first, then every 100th).
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass

from posed.daemon.bus import ros2_messages as rm
from posed.daemon.config.sections import Ros2Config

ADMIN_SPACE = "@ros2_lv"
QOS_DEFAULT = "::,10:,:,:,,"      # reliable, volatile, keep last 10, no deadline/lifespan, automatic liveliness
NODE_ID = 0
LOG_ERROR_EVERY = 100


def fully_qualified(namespace: str, topic: str) -> str:
    """``/ns/topic`` for a relative ``topic``; an absolute one stays as it is."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


def mangle(name: str) -> str:
    """rmw_zenoh's mangling: every ``/`` becomes ``%``; an empty name is ``%``."""
    return name.replace("/", "%") if name else "%"


def topic_key(domain_id: int, fq_topic: str, ros_type: str, distro: str = "jazzy") -> str:
    return f"{domain_id}/{fq_topic.strip('/')}/{rm.dds_type_name(ros_type)}/{rm.type_hash(ros_type, distro)}"


def node_token(domain_id: int, zid: str, namespace: str, node_name: str, node_id: int = NODE_ID) -> str:
    return (f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{node_id}/NN/%/{mangle(namespace or '/')}/"
            f"{node_name}")


def publisher_token(domain_id: int, zid: str, namespace: str, node_name: str, entity_id: int, fq_topic: str,
                    ros_type: str, distro: str = "jazzy", qos: str = QOS_DEFAULT, node_id: int = NODE_ID) -> str:
    return (f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{entity_id}/MP/%/{mangle(namespace or '/')}/{node_name}/"
            f"{mangle(fq_topic)}/{rm.dds_type_name(ros_type)}/{rm.type_hash(ros_type, distro)}/{qos}")


def attachment(seq: int, t_ns: int, gid: bytes) -> bytes:
    """The rmw_zenoh publication attachment: int64 seq, int64 source time (ns), GID length + GID (33 bytes)."""
    from zenoh.ext import Int64, z_serialize

    return z_serialize((Int64(seq), Int64(t_ns), bytes(gid))).to_bytes()


@dataclass
class _Endpoint:
    ros_type: str
    topic: str              # fully qualified
    key: str
    gid: bytes
    entity_id: int
    reliable: bool = False
    publisher: object = None
    seq: int = 0
    sent: int = 0


class Ros2Bridge:
    """The ROS 2 publishers on the publisher stage's session; ``open`` when the session opens, then
    ``publish_pose`` per frame and ``publish_event`` per fall-event message sent."""

    def __init__(self, cfg: Ros2Config, log) -> None:
        self.cfg = cfg
        self.log = log
        ns = cfg.namespace
        self.endpoints = {
            name: _Endpoint(ros_type, fq, topic_key(cfg.domain_id, fq, ros_type, cfg.distro), os.urandom(16), i + 1,
                            reliable=(name == "fall"))
            for i, (name, ros_type, topic) in enumerate((
                ("joint_states", rm.JOINT_STATE, cfg.joint_states_topic),
                ("skeleton", rm.MARKER_ARRAY, cfg.skeleton_topic),
                ("position", rm.POINT_STAMPED, cfg.position_topic),
                ("fall", rm.DIAGNOSTIC_ARRAY, cfg.fall_topic)))
            for fq in [fully_qualified(ns, topic)]}
        self._tokens: list = []
        self.errors = 0
        self.zid = ""
        self._person = False

    @property
    def is_open(self) -> bool:
        return bool(self._tokens)

    def open(self, session, stack: contextlib.ExitStack | None = None) -> None:
        """Declare the publishers and the liveliness tokens (node, then each publisher)."""
        import zenoh

        self.zid = str(session.zid())
        cfg = self.cfg
        self._tokens = [session.liveliness().declare_token(
            node_token(cfg.domain_id, self.zid, cfg.namespace, cfg.node_name))]
        for ep in self.endpoints.values():
            ep.publisher = session.declare_publisher(
                ep.key, encoding=zenoh.Encoding.APPLICATION_CDR,
                congestion_control=zenoh.CongestionControl.BLOCK if ep.reliable else zenoh.CongestionControl.DROP,
                reliability=zenoh.Reliability.RELIABLE)
            self._tokens.append(session.liveliness().declare_token(publisher_token(
                cfg.domain_id, self.zid, cfg.namespace, cfg.node_name, ep.entity_id, ep.topic, ep.ros_type,
                cfg.distro)))
        if stack is not None:
            stack.callback(self.release)
        self.log.info("ros2_open", domain_id=cfg.domain_id, node=cfg.node_name, namespace=cfg.namespace or "/",
                      topics={n: ep.topic for n, ep in self.endpoints.items()}, distro=cfg.distro)

    def release(self) -> None:
        for entity in [*self._tokens, *(ep.publisher for ep in self.endpoints.values() if ep.publisher)]:
            try:
                entity.undeclare()
            except Exception:
                pass
        self._tokens = []
        for ep in self.endpoints.values():
            ep.publisher = None

    def _put(self, name: str, msg) -> bool:
        ep = self.endpoints[name]
        if ep.publisher is None or msg is None:
            return False
        payload = rm.serialize(msg, ep.ros_type)
        ep.seq += 1
        ep.publisher.put(payload, attachment=attachment(ep.seq, time.time_ns(), ep.gid))
        ep.sent += 1
        return True

    def _failed(self, what: str, exc: Exception) -> None:
        self.errors += 1
        if self.errors == 1 or self.errors % LOG_ERROR_EVERY == 0:
            self.log.error("ros2_publish_failed", what=what, error=repr(exc), errors=self.errors)

    def publish_pose(self, pose: dict) -> None:
        """JointState, the skeleton and the position of one pose message (``posed.pose``); when the person is
        lost, the skeleton is cleared once."""
        if not self.is_open:
            return
        cfg = self.cfg
        try:
            if pose.get("ok") and pose.get("time_unix") is not None:
                self._person = True
                self._put("joint_states", rm.joint_state(pose, cfg.frame_id))
                self._put("skeleton", rm.skeleton(pose, cfg.frame_id, cfg.body_frame_id))
                self._put("position", rm.position(pose, cfg.frame_id))
            elif self._person:
                self._person = False
                self._put("skeleton", rm.clear_skeleton(pose.get("time_unix") or time.time(), cfg.frame_id))
        except Exception as exc:
            self._failed("pose", exc)

    def publish_event(self, event: dict) -> None:
        """One fall-event message (``posed.fall_event``) as a DiagnosticArray."""
        if not self.is_open:
            return
        try:
            self._put("fall", rm.fall_diagnostic(event, self.cfg.node_name))
        except Exception as exc:
            self._failed("fall event", exc)

    def status(self) -> dict:
        """The ``ros2`` part of the status object."""
        return {"open": self.is_open, "domain_id": self.cfg.domain_id, "node": self.cfg.node_name,
                "published": {n: ep.sent for n, ep in self.endpoints.items()}, "errors": self.errors}
