"""Configuration sections owned by the daemon itself: ``pipeline``, ``zenoh``, ``logging``, ``hooks``, ``web``,
``ros2`` and ``privacy``."""

from __future__ import annotations

import re
from dataclasses import dataclass, field


@dataclass(frozen=True)
class PipelineConfig:
    """The supervised stage processes and their frame budget."""

    target_fps: float = field(
        default=10.0, metadata={"doc": "frames per second the pipeline takes from the camera", "unit": "Hz",
                                "range": (0.5, 60.0)}
    )
    ring_slots: int = field(
        default=4, metadata={"doc": "shared-memory frame slots between capture and landmark stage",
                             "range": (2, 64)}
    )
    stuck_after_s: float = field(
        default=5.0, metadata={"doc": "a stage busy on one step longer than this is stuck and restarted",
                               "unit": "s", "range": (0.5, 600.0)}
    )
    max_restarts: int = field(
        default=5, metadata={"doc": "restarts allowed within restart_window_s before escalating to systemd",
                             "range": (1, 1000)}
    )
    restart_window_s: float = field(
        default=60.0, metadata={"doc": "window for max_restarts", "unit": "s", "range": (1.0, 3600.0)}
    )
    status_period_s: float = field(
        default=1.0, metadata={"doc": "period of the status topic and stats log", "unit": "s",
                               "range": (0.1, 60.0)}
    )
    state_dir: str = field(
        default="", metadata={"doc": "where events and history live; empty = $XDG_STATE_HOME/posed "
                                     "(the service: $STATE_DIRECTORY)"}
    )
    startup_timeout_s: float = field(
        default=180.0, metadata={"doc": "a stage still warming up (model load, numba compile) after this is "
                                        "stuck and restarted", "unit": "s", "range": (5.0, 3600.0)}
    )
    backoff_max_s: float = field(
        default=10.0, metadata={"doc": "longest wait before restarting a stage (the first restart is at once, "
                                       "then 0.5 s doubling)", "unit": "s", "range": (0.5, 600.0)}
    )
    shutdown_timeout_s: float = field(
        default=4.0, metadata={"doc": "on SIGTERM/SIGINT, stages still running after this are killed",
                               "unit": "s", "range": (0.5, 60.0)}
    )
    frame_max_pixels: int = field(
        default=1280 * 720, metadata={"doc": "the working size: largest frame (width x height) a ring slot "
                                             "holds; a larger frame is scaled down at capture by the smallest "
                                             "whole factor that fits (landmarks stay in the source's pixels)",
                                      "unit": "px",
                                      "range": (160 * 120, 8192 * 8192)}
    )
    stop_at_end: bool = field(
        default=False, metadata={"doc": "file sources: stop the daemon (exit 0) once the recording has "
                                        "ended and the pipeline is empty"}
    )


@dataclass(frozen=True)
class ZenohConfig:
    """The Zenoh session; the default exposes nothing beyond this machine."""

    mode: str = field(default="peer", metadata={"doc": "session mode", "choices": ("peer", "client")})
    listen: tuple[str, ...] = field(
        default=("tcp/127.0.0.1:7447",), metadata={"doc": "endpoints to listen on"}
    )
    connect: tuple[str, ...] = field(default=(), metadata={"doc": "endpoints (routers/peers) to connect to"})
    multicast_scouting: bool = field(default=False, metadata={"doc": "UDP multicast discovery on the LAN"})
    config_file: str = field(
        default="", metadata={"doc": "native Zenoh JSON5 config (TLS, user/password, access control); "
                                     "the keys above override it"}
    )
    publish_images: bool = field(
        default=False, metadata={"doc": "privacy: never publish images unless true (not implemented: "
                                        "topics carry landmarks, poses and events only)"}
    )
    publish_landmarks: bool = field(
        default=True, metadata={"doc": "publish the 2D landmarks of each frame on posed/ROBOT/landmarks"}
    )
    event_republish_s: float = field(
        default=30.0, metadata={"doc": "fall events nobody acknowledged (posed/ROBOT/events/ack) are "
                                       "published again this often, and when a subscriber appears",
                                "unit": "s", "range": (1.0, 86400.0)}
    )
    reconnect_s: float = field(
        default=5.0, metadata={"doc": "retry opening the session this often when it fails (client mode "
                                      "without a reachable router, a busy listen port)", "unit": "s",
                               "range": (0.5, 600.0)}
    )

    def __post_init__(self) -> None:
        problems = []
        for key in ("listen", "connect"):
            for ep in getattr(self, key):
                if not re.fullmatch(r"(tcp|udp|tls|quic|ws|unixsock-stream|unixpipe|serial|vsock)/\S+", ep):
                    problems.append(f"{key}: {ep!r} is not a Zenoh endpoint such as tcp/127.0.0.1:7447 "
                                    "or tls/host:7447")
        if self.mode == "client" and not self.connect:
            problems.append("connect: client mode needs at least one router or peer to connect to, "
                            "e.g. [tcp/192.168.1.10:7447]; or use mode: peer")
        if problems:
            raise ValueError("; ".join(problems))


@dataclass(frozen=True)
class LoggingConfig:
    """structlog output: journald's own fields under systemd, readable on a terminal, JSON lines otherwise."""

    level: str = field(
        default="info", metadata={"doc": "lowest level logged", "choices": ("debug", "info", "warning", "error")}
    )
    format: str = field(
        default="auto", metadata={"doc": "auto = journal when journald collects the output (systemd), else "
                                         "console on a TTY, else JSON; journal = structured journald entries "
                                         "(POSED_STAGE, POSED_ROBOT, POSED_EVENT_ID, PRIORITY ...)",
                                  "choices": ("auto", "console", "json", "journal")}
    )
    stats_period_s: float = field(
        default=10.0, metadata={"doc": "period of the stats log event", "unit": "s", "range": (1.0, 3600.0)}
    )


@dataclass(frozen=True)
class HookConfig:
    """One command run on each fall event: an argv list (never a shell), event JSON on stdin."""

    argv: tuple[str, ...] = field(default=(), metadata={"doc": "program and arguments"})
    timeout_s: float = field(default=10.0, metadata={"doc": "kill after", "unit": "s", "range": (0.1, 3600.0)})
    retries: int = field(default=2, metadata={"doc": "extra attempts after a failure", "range": (0, 100)})


@dataclass(frozen=True)
class HooksConfig:
    """Commands run on fall events, when posed stops and resumes watching, and when the person is long unseen."""

    on_event: tuple[HookConfig, ...] = field(default=(), metadata={"doc": "hooks run for every fall event"})
    on_watch_lost: tuple[HookConfig, ...] = field(default=(), metadata={
        "doc": "hooks run once when posed has not been watching for watch_lost_after_s (camera lost, blind or "
               "ended, a stage failing: no fall could be alarmed), and once when it watches again "
               "(POSED_WATCH=lost / back; docs/daemon.md)"})
    watch_lost_after_s: float = field(default=60.0, metadata={
        "doc": "how long posed must not have been watching before on_watch_lost runs; above the routine "
               "recoveries (a stage restart about 2 s, a camera reconnect up to source.reconnect_max_s), so "
               "those call nobody", "unit": "s", "range": (1.0, 86400.0)})
    on_absent: tuple[HookConfig, ...] = field(default=(), metadata={
        "doc": "hooks run once when the person has not been seen for longer than usual (falls.absence_margin_h "
               "past the latest they were back on any of the last falls.absence_days days at this time of day: "
               "maybe fallen in another room), and once when they are seen again (POSED_ABSENT=absent / back; "
               "docs/daemon.md)"})
    retry_delay_s: float = field(
        default=2.0, metadata={"doc": "wait before the n-th retry: n times this", "unit": "s",
                               "range": (0.0, 600.0)}
    )
    output_limit: int = field(
        default=4096, metadata={"doc": "bytes of a hook's stdout and of its stderr that are logged",
                                "unit": "B", "range": (0, 1048576)}
    )
    queue_limit: int = field(
        default=100, metadata={"doc": "events waiting for each hook; when full the oldest waiting one is "
                                      "dropped (counted and logged; it stays in the journal)",
                               "range": (1, 100000)}
    )


@dataclass(frozen=True)
class WebConfig:
    """The live web view (posed web): what the Zenoh topics carry, in a browser; never an image."""

    enabled: bool = field(
        default=False, metadata={"doc": "serve the page from the daemon itself (a stage of its own, started and "
                                        "watched by the supervisor); otherwise run `posed web` beside it"}
    )
    host: str = field(
        default="127.0.0.1", metadata={"doc": "address the page is served on; anything but a loopback address "
                                              "(127.0.0.1, ::1, localhost) needs a token"}
    )
    port: int = field(default=8780, metadata={"doc": "TCP port of the page", "range": (1, 65535)})
    token: str = field(
        default="", metadata={"doc": "secret every request must carry (?token=... in the page's address); "
                                     "required when host is not a loopback address; at least 16 characters"}
    )
    pose_rate_hz: float = field(
        default=15.0, metadata={"doc": "most poses per second sent to each browser", "unit": "Hz",
                                "range": (1.0, 60.0)}
    )

    def __post_init__(self) -> None:
        loopback = self.host in ("127.0.0.1", "::1", "localhost")
        if not loopback and not self.token:
            raise ValueError(f"token: serving on {self.host!r} (beyond this machine) needs a token of at least "
                             "16 characters; or keep host: 127.0.0.1")
        if self.token and len(self.token) < 16:
            raise ValueError("token: at least 16 characters (e.g. the output of `openssl rand -hex 16`)")


ROS2_TOPIC = r"/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*"


@dataclass(frozen=True)
class Ros2Config:
    """ROS 2 robots see posed through rmw_zenoh (docs/ros2.md): standard messages on the daemon's Zenoh session."""

    enabled: bool = field(
        default=False, metadata={"doc": "publish JointState, a skeleton MarkerArray, the person's position and fall "
                                        "diagnostics with rmw_zenoh's key expressions (join the ROS router with "
                                        "zenoh.connect)"}
    )
    domain_id: int = field(default=0, metadata={"doc": "ROS_DOMAIN_ID of the ROS 2 robots", "range": (0, 232)})
    distro: str = field(
        default="jazzy", metadata={"doc": "ROS 2 distribution of the subscribers: type hashes (RIHS01) from jazzy "
                                          "on; humble's rmw_zenoh uses TypeHashNotSupported",
                                   "choices": ("jazzy", "humble")}
    )
    namespace: str = field(
        default="", metadata={"doc": "ROS namespace of the posed node and of relative topic names, e.g. /robot1",
                              "pattern": r"(/[A-Za-z][A-Za-z0-9_]*)*"}
    )
    node_name: str = field(default="posed", metadata={"doc": "the ROS node name", "pattern": r"[A-Za-z][A-Za-z0-9_]*"})
    joint_states_topic: str = field(
        default="posed/joint_states", metadata={"doc": "sensor_msgs/msg/JointState: the 23 joint angles, radians",
                                                "pattern": ROS2_TOPIC}
    )
    skeleton_topic: str = field(
        default="posed/skeleton", metadata={"doc": "visualization_msgs/msg/MarkerArray: the skeleton (RViz)",
                                            "pattern": ROS2_TOPIC}
    )
    position_topic: str = field(
        default="posed/person_position", metadata={"doc": "geometry_msgs/msg/PointStamped: the mid-hip in the "
                                                          "camera frame (root_cam_m), when known",
                                                   "pattern": ROS2_TOPIC}
    )
    fall_topic: str = field(
        default="posed/fall_events", metadata={"doc": "diagnostic_msgs/msg/DiagnosticArray: fall events",
                                               "pattern": ROS2_TOPIC}
    )
    frame_id: str = field(
        default="camera_color_optical_frame", metadata={"doc": "TF frame of the camera (optical: x right, y down, "
                                                               "z forward; posed's camera frame)"}
    )
    body_frame_id: str = field(
        default="posed_mid_hip", metadata={"doc": "frame of a skeleton whose position is unknown (no intrinsics): "
                                                  "camera-aligned axes, origin at the person's mid-hip"}
    )


@dataclass(frozen=True)
class PrivacyConfig:
    """Pausing the watching for privacy, asked on posed/ROBOT/privacy/pause (docs/daemon.md, "Pausing for privacy")."""

    allow_pause: bool = field(
        default=True, metadata={"doc": "whether a pause may be asked for on posed/ROBOT/privacy/pause (resuming is "
                                       "always allowed); false: every pause is refused with this key named"}
    )
    max_pause_s: float = field(
        default=3600.0, metadata={"doc": "the longest pause; a longer one asked for is cut to this (the reply says "
                                         "clamped: true); watching resumes by itself when a pause ends",
                                  "unit": "s", "range": (60.0, 86400.0)}
    )
