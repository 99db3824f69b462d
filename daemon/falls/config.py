"""Configuration of fall detection (section ``falls``) and event hooks (section ``hooks``)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class FallsConfig:
    """Fall detector thresholds; each one's reason is in docs/falls.md."""

    enabled: bool = field(default=True, metadata={"doc": "run the fall detector"})
    alarm_after_s: float = field(
        default=10.0, metadata={"doc": "on the floor this long without recovering raises the alarm",
                                "unit": "s", "range": (0.0, 600.0)}
    )
    camera_tilt_deg: float = field(
        default=0.0, metadata={"doc": "camera pitch, down positive (for trunk inclination against gravity)",
                               "unit": "deg", "range": (-90.0, 90.0)}
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
