"""posed's messages as standard ROS 2 messages, CDR-encoded by ``rosbags`` (its Jazzy type store: the message
definitions, the REP-2016 type hashes and the CDR serializer; nothing here encodes CDR by hand).

* ``sensor_msgs/msg/JointState``: the joint angles the frame measured (fitting.measured; the others left
  out), by URDF-style names (``left_knee_joint``, ``URDF_JOINT_NAMES``), radians;
* ``visualization_msgs/msg/MarkerArray``: the measured skeleton — a LINE_LIST of bones and a SPHERE_LIST of
  joints — in
  the camera's optical frame (x right, y down, z forward: posed's camera frame), metres, at ``root_cam_m``; in
  the body frame (origin at the mid-hip, camera-aligned axes) when the position is unknown; one DELETEALL
  marker when the person is lost;
* ``geometry_msgs/msg/PointStamped``: ``root_cam_m``, the mid-hip in the camera frame, when known;
* ``diagnostic_msgs/msg/DiagnosticArray``: a fall-event message as one DiagnosticStatus (level by state, the
  event's fields as key/value pairs; see docs/ros2.md for why this type).

Every header stamp is the capture time as unix time (``time_unix``), so ROS tools line it up with their own
clocks.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

JOINT_STATE = "sensor_msgs/msg/JointState"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
TYPES = (JOINT_STATE, MARKER_ARRAY, POINT_STAMPED, DIAGNOSTIC_ARRAY)

BONES = (("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"),
         ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
         ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"),
         ("left_shoulder", "left_hip"), ("right_shoulder", "right_hip"),
         ("left_hip", "left_knee"), ("left_knee", "left_ankle"),
         ("right_hip", "right_knee"), ("right_knee", "right_ankle"))
# posed's joint angle -> the name a humanoid URDF gives that joint: <side>_<joint>_<pitch|roll|yaw>_joint, the
# scheme of common humanoid URDFs (Unitree G1's joints are named so: left_hip_pitch_joint, waist_yaw_joint,
# left_elbow_joint, ...). theta (flexion, about the body's left-right axis) is pitch, phi (adduction, side
# bend) roll, psi (rotation) yaw. Values keep posed's sign convention (docs/ros2.md).
URDF_JOINT_NAMES = {
    "theta_hd": "head_pitch_joint", "psi_hd": "head_yaw_joint",
    "theta_tr": "waist_pitch_joint", "phi_tr": "waist_roll_joint", "psi_tr": "waist_yaw_joint",
    **{f"{axis}_{joint}_{s}": f"{side}_{name}_joint"
       for s, side in (("l", "left"), ("r", "right"))
       for axis, joint, name in (("theta", "sh", "shoulder_pitch"), ("phi", "sh", "shoulder_roll"),
                                 ("theta", "el", "elbow"), ("theta", "hp", "hip_pitch"), ("phi", "hp", "hip_roll"),
                                 ("psi", "hp", "hip_yaw"), ("theta", "kn", "knee"), ("theta", "an", "ankle_pitch"),
                                 ("phi", "an", "ankle_roll"))},
}
MARKER_NS = "posed_skeleton"
MARKER_LIFETIME_S = 1.0           # a skeleton not refreshed for this long disappears from RViz
DIAGNOSTIC_LEVEL = {"falling": 1, "on_floor": 2, "alarm": 2, "recovered": 0}   # WARN, ERROR, ERROR, OK
EVENT_KEYS = ("id", "robot", "state", "confidence", "time_unix", "t_onset_unix", "t_impact_unix", "wall_time")
PERSON_KEYS = ("person", "member")


@cache
def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def dds_type_name(ros_type: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (the DDS name rmw_zenoh puts in its keys)."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def type_hash(ros_type: str, distro: str = "jazzy") -> str:
    """The REP-2016 hash ``RIHS01_<sha256>`` (Iron, Jazzy and later); Humble has none: ``TypeHashNotSupported``."""
    return "TypeHashNotSupported" if distro == "humble" else typestore().hash_rihs01(ros_type)


def msg_definition(ros_type: str) -> str:
    """The full message definition text (with its dependencies), as a ROS install would give it."""
    return typestore().generate_msgdef(ros_type, ros_version=2)[0]


def serialize(msg, ros_type: str) -> bytes:
    """CDR (little endian, with its 4-byte encapsulation header)."""
    return bytes(typestore().serialize_cdr(msg, ros_type))


def _t(name: str):
    return typestore().types[name]


def stamp(time_unix: float):
    sec = math.floor(time_unix)
    return _t("builtin_interfaces/msg/Time")(sec=int(sec), nanosec=int(round((time_unix - sec) * 1e9)) % 1_000_000_000)


def header(time_unix: float, frame_id: str):
    return _t("std_msgs/msg/Header")(stamp=stamp(time_unix), frame_id=frame_id)


def measured_pose(pose: dict):
    """The pose message as a ``fitting.FitResult``: what it measured (``measured``, fitting.measured) decides
    what goes out."""
    from posed.fitting import FitResult

    return FitResult.from_json({"seq": 0, "t": 0.0, **pose})   # seq and t are not needed here


def joint_state(pose: dict, frame_id: str):
    """JointState of an ok pose: the joint angles this frame measured (fitting.measured; the others are left
    out, so a message may name fewer joints than the last), by their URDF-style names (``URDF_JOINT_NAMES``),
    positions in radians in posed's sign convention; velocity and effort empty."""
    from posed.fitting import JOINT_ANGLE_NAMES

    angles = measured_pose(pose).measured_angles()
    names = [n for n in JOINT_ANGLE_NAMES if n in angles]
    return _t(JOINT_STATE)(header=header(pose["time_unix"], frame_id), name=[URDF_JOINT_NAMES[n] for n in names],
                           position=np.radians(np.array([angles[n] for n in names], dtype=np.float64)),
                           velocity=np.zeros(0), effort=np.zeros(0))


def _point(xyz):
    return _t("geometry_msgs/msg/Point")(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


def _marker(hdr, marker_id: int, kind: int, action: int, points, scale: float, rgba):
    T = _t
    return T("visualization_msgs/msg/Marker")(
        header=hdr, ns=MARKER_NS, id=marker_id, type=kind, action=action,
        pose=T("geometry_msgs/msg/Pose")(position=_point((0, 0, 0)),
                                         orientation=T("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0)),
        scale=T("geometry_msgs/msg/Vector3")(x=scale, y=scale, z=scale),
        color=T("std_msgs/msg/ColorRGBA")(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
        lifetime=T("builtin_interfaces/msg/Duration")(sec=int(MARKER_LIFETIME_S),
                                                       nanosec=int(MARKER_LIFETIME_S % 1 * 1e9)),
        frame_locked=False, points=points, colors=[], texture_resource="",
        texture=T("sensor_msgs/msg/CompressedImage")(header=hdr, format="", data=np.zeros(0, dtype=np.uint8)),
        uv_coordinates=[], text="", mesh_resource="",
        mesh_file=T("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False)


def skeleton(pose: dict, frame_id: str, body_frame_id: str):
    """MarkerArray of an ok pose: bones (LINE_LIST, id 0) and joints (SPHERE_LIST, id 1) of the joints this
    frame measured (fitting.measured; a bone when both its ends were), metres, in ``frame_id`` at
    ``root_cam_m``, or in ``body_frame_id`` (mid-hip origin) when the position is unknown."""
    j3 = {k: v for k, v in measured_pose(pose).measured_joints().items()
          if v is not None and all(isinstance(c, (int, float)) for c in v)}
    root = pose.get("root_cam_m")
    known = root is not None and all(isinstance(c, (int, float)) for c in root)
    offset = np.array(root if known else (0.0, 0.0, 0.0), dtype=np.float64)
    hdr = header(pose["time_unix"], frame_id if known else body_frame_id)
    at = {k: _point(np.asarray(v, dtype=np.float64) + offset) for k, v in j3.items()}
    M = _t("visualization_msgs/msg/Marker")
    bones = [p for a, b in BONES if a in at and b in at for p in (at[a], at[b])]
    return _t(MARKER_ARRAY)(markers=[
        _marker(hdr, 0, M.LINE_LIST, M.ADD, bones, 0.02, (0.1, 0.8, 0.2, 1.0)),
        _marker(hdr, 1, M.SPHERE_LIST, M.ADD, list(at.values()), 0.05, (1.0, 0.6, 0.1, 1.0))])


def clear_skeleton(time_unix: float, frame_id: str):
    """A MarkerArray with one DELETEALL marker: the person is gone."""
    M = _t("visualization_msgs/msg/Marker")
    return _t(MARKER_ARRAY)(markers=[_marker(header(time_unix, frame_id), 0, M.LINE_LIST, M.DELETEALL, [], 0.0,
                                             (0.0, 0.0, 0.0, 0.0))])


def position(pose: dict, frame_id: str):
    """PointStamped of ``root_cam_m`` (None when unknown)."""
    root = pose.get("root_cam_m")
    if root is None or not all(isinstance(c, (int, float)) for c in root):
        return None
    return _t(POINT_STAMPED)(header=header(pose["time_unix"], frame_id), point=_point(root))


def fall_diagnostic(event: dict, node_name: str):
    """DiagnosticArray with one DiagnosticStatus: name ``<node>/fall``, level WARN (falling), ERROR (on_floor,
    alarm) or OK (recovered), message ``fall <state>``, hardware_id the robot, values the event's fields."""
    T = _t
    values = [T("diagnostic_msgs/msg/KeyValue")(key=k, value="" if event.get(k) is None else str(event[k]))
              for k in EVENT_KEYS]
    values.append(T("diagnostic_msgs/msg/KeyValue")(key="features", value=",".join(event.get("features") or ())))
    for k in PERSON_KEYS:                # several people: whose fall (absent with one person)
        if event.get(k) is not None:
            values.append(T("diagnostic_msgs/msg/KeyValue")(key=k, value=str(event[k])))
    level = DIAGNOSTIC_LEVEL.get(event.get("state"), 2)
    status = T("diagnostic_msgs/msg/DiagnosticStatus")(
        level=level, name=f"{node_name}/fall",
        message=f"fall {event.get('state')}", hardware_id=str(event.get("robot", "")), values=values)
    t = event.get("time_unix")
    return T(DIAGNOSTIC_ARRAY)(header=header(float(t) if t is not None else 0.0, ""), status=[status])
