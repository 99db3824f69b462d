"""The control segment: the health board and the mailboxes, in one shared-memory segment.

Created (and unlinked) by the supervisor; each stage process attaches with the picklable
:class:`ControlSpec` and the doorbell semaphores it was given at spawn.
"""

from __future__ import annotations

from dataclasses import dataclass

from posed.daemon.proc import shm
from posed.daemon.proc.health import HealthBoard
from posed.daemon.proc.mailbox import Mailbox

# name -> capacity in bytes. frames: capture -> landmarks (FrameRef); landmarks: -> fitting; fits: ->
# publisher; status: supervisor -> publisher; mount: publisher -> fitting (the robot's camera poses,
# daemon.stages.mount_samples.MountSamples: at most 64 samples of ~250 bytes); privacy: publisher -> capture (the
# pause for privacy, daemon.stages.privacy_gate.PrivacyOrder, polled); report.<stage>: stage -> supervisor
# (fatal errors, camera info, the publisher's pause for privacy).
MAILBOXES = {"frames": 4096, "landmarks": 65536, "fits": 131072, "status": 65536, "mount": 32768, "privacy": 4096}
REPORT_CAPACITY = 16384
DOORBELLS = ("frames", "landmarks", "fits")


@dataclass(frozen=True)
class ControlSpec:
    name: str
    stages: tuple[str, ...]

    def layout(self) -> tuple[dict[str, tuple[int, int]], int]:
        """Mailbox name -> (offset, capacity) and the board's offset (board first)."""
        off = HealthBoard.size(len(self.stages))
        boxes = {}
        for name, cap in [*MAILBOXES.items(), *((f"report.{s}", REPORT_CAPACITY) for s in self.stages)]:
            boxes[name] = (off, cap)
            off += Mailbox.size(cap)
            off = (off + 63) // 64 * 64
        return boxes, off


class Control:
    """Board plus mailboxes over one segment."""

    def __init__(self, spec: ControlSpec, segment, owner: bool, doorbells: dict | None) -> None:
        self.spec = spec
        self._segment = segment
        self._owner = owner
        self.board = HealthBoard(spec.stages, segment.buf, 0)
        boxes, _ = spec.layout()
        doorbells = doorbells or {}
        self.mailboxes = {name: Mailbox(name, segment.buf, off, cap, doorbells.get(name))
                          for name, (off, cap) in boxes.items()}

    @classmethod
    def create(cls, stages: tuple[str, ...], doorbells: dict) -> Control:
        _, size = ControlSpec("", stages).layout()
        segment = shm.create("control", size)
        return cls(ControlSpec(segment.name, stages), segment, owner=True, doorbells=doorbells)

    @classmethod
    def attach(cls, spec: ControlSpec, doorbells: dict) -> Control:
        return cls(spec, shm.attach(spec.name), owner=False, doorbells=doorbells)

    def mailbox(self, name: str) -> Mailbox:
        return self.mailboxes[name]

    def close(self) -> None:
        self.board.detach()
        for box in self.mailboxes.values():
            box.detach()
        shm.release(self._segment, self._owner)
