"""Configuration sections owned by the daemon itself: ``pipeline``, ``zenoh``, ``logging`` and ``hooks``."""

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
        default=1280 * 720, metadata={"doc": "largest frame (width x height) a ring slot holds; the camera's "
                                             "configured size is always allowed", "unit": "px",
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
    """structlog output: readable on a terminal, JSON lines otherwise (journald collects stdout)."""

    level: str = field(
        default="info", metadata={"doc": "lowest level logged", "choices": ("debug", "info", "warning", "error")}
    )
    format: str = field(
        default="auto", metadata={"doc": "auto = console on a TTY, JSON otherwise",
                                  "choices": ("auto", "console", "json")}
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
    """Commands run on fall events."""

    on_event: tuple[HookConfig, ...] = field(default=(), metadata={"doc": "hooks run for every fall event"})
    retry_delay_s: float = field(
        default=2.0, metadata={"doc": "wait before the n-th retry: n times this", "unit": "s",
                               "range": (0.0, 600.0)}
    )
    output_limit: int = field(
        default=4096, metadata={"doc": "bytes of a hook's stdout and of its stderr that are logged",
                                "unit": "B", "range": (0, 1048576)}
    )
