"""The Zenoh key expressions (interfaces.md section 4); ROBOT is ``Config.robot_id``."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Topics:
    robot: str

    @property
    def root(self) -> str:
        return f"posed/{self.robot}"

    @property
    def pose(self) -> str:
        return f"{self.root}/pose"

    @property
    def landmarks(self) -> str:
        return f"{self.root}/landmarks"

    @property
    def status(self) -> str:
        return f"{self.root}/status"

    @property
    def events_fall(self) -> str:
        return f"{self.root}/events/fall"

    @property
    def events_ack(self) -> str:
        """Receivers put an event id here to acknowledge it (payload: the id, or JSON {"id": ...})."""
        return f"{self.root}/events/ack"

    @property
    def camera_mount(self) -> str:
        """The robot puts its camera's pose here (daemon.bus.camera_mount; ``falls.camera_mount_from_bus``)."""
        return f"{self.root}/camera/mount"

    @property
    def privacy_pause(self) -> str:
        """Queryable: the robot's software asks posed to stop watching for a while, or to resume
        (daemon.bus.pause_query; docs/daemon.md, "Pausing for privacy")."""
        return f"{self.root}/privacy/pause"

    @property
    def alive(self) -> str:
        return f"{self.root}/alive"

    def daemon(self, instance: str) -> str:
        """This daemon's own liveliness token (daemon.bus.robot_claim): ``alive/<instance>``."""
        return f"{self.alive}/{instance}"

    @property
    def daemons(self) -> str:
        """Every daemon's token under this robot id (more than one: two daemons share the robot id)."""
        return f"{self.alive}/*"

    @property
    def state(self) -> str:
        return f"{self.root}/state"

    @property
    def history(self) -> str:
        return f"{self.root}/events/history"
