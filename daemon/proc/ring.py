"""The shared-memory frame ring between the capture stage and the landmark stage.

Layout of the one segment (created and unlinked by the supervisor, attached by the stages)::

    header   slots x 8 int64   [lock, seq, width, height, has_depth, 0, 0, 0]
    times    slots x 2 float64 [t_capture (monotonic s), depth_scale (m per unit)]
    images   slots x capacity_px x 3 uint8   (BGR, row-major, width x height used)
    depths   slots x capacity_px uint16      (only when the source can give depth)

Each slot is guarded by a sequence lock: the writer makes ``lock`` odd, writes, then makes it even again; a
reader copies the pixels out and keeps them only if ``lock`` was even and unchanged around the copy and the
slot still holds the frame its :class:`~daemon.messages.FrameRef` names. A frame overwritten before the
reader got to it is simply dropped (the newest wins). There is one writer (the capture stage) and one reader
(the landmark stage); x86-64 keeps stores and loads in program order, which the lock relies on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posed.camera_model import Intrinsics
from posed.daemon.messages import FrameRef
from posed.daemon.proc import shm

_HDR = 8


@dataclass(frozen=True)
class RingSpec:
    """What a stage needs to attach to the ring (picklable)."""

    name: str
    slots: int
    capacity_px: int
    with_depth: bool

    @property
    def size(self) -> int:
        depth = self.slots * self.capacity_px * 2 if self.with_depth else 0
        return self.slots * (_HDR * 8 + 16 + self.capacity_px * 3) + depth


class FrameTooLarge(ValueError):
    """A frame has more pixels than a ring slot holds."""


def too_large_fix(pixels: int) -> str:
    """What to do about an image of ``pixels`` that no source decodes (more than ``hal.MAX_DECODE_PIXELS``;
    anything smaller is scaled down to a ring slot at capture, never skipped for its size)."""
    from posed.hal import MAX_DECODE_PIXELS

    return (f"scale the image down to at most {MAX_DECODE_PIXELS} pixels (7680x4320, 8K UHD), the largest frame "
            f"posed decodes (it has {pixels}); anything up to that is scaled down to a ring slot at capture")


class FrameRing:
    """A view of the ring; :meth:`create` in the supervisor, :meth:`attach` in the stages."""

    def __init__(self, spec: RingSpec, segment, owner: bool) -> None:
        self.spec = spec
        self._segment = segment
        self._owner = owner
        buf = segment.buf
        n, cap = spec.slots, spec.capacity_px
        off = 0
        self._hdr = np.ndarray((n, _HDR), np.int64, buf, off)
        off += n * _HDR * 8
        self._times = np.ndarray((n, 2), np.float64, buf, off)
        off += n * 16
        self._images = np.ndarray((n, cap * 3), np.uint8, buf, off)
        off += n * cap * 3
        self._depths = np.ndarray((n, cap), np.uint16, buf, off) if spec.with_depth else None
        self._next = 0

    @classmethod
    def create(cls, slots: int, capacity_px: int, with_depth: bool) -> FrameRing:
        spec = RingSpec("", slots, capacity_px, with_depth)
        segment = shm.create("ring", spec.size)
        spec = RingSpec(segment.name, slots, capacity_px, with_depth)
        ring = cls(spec, segment, owner=True)
        ring._hdr[:] = 0
        ring._hdr[:, 1] = -1
        return ring

    @classmethod
    def attach(cls, spec: RingSpec) -> FrameRing:
        return cls(spec, shm.attach(spec.name), owner=False)

    def write(self, image: np.ndarray, seq: int, t_capture: float, depth: np.ndarray | None = None,
              depth_scale: float = 0.0, intrinsics: Intrinsics | None = None,
              t_origin: float | None = None, gravity: tuple[float, float, float] | None = None,
              scale: int = 1, source_size: tuple[int, int] | None = None) -> FrameRef:
        """Copy one frame (H x W x 3 uint8, optional H x W uint16 depth) into the next slot; ``gravity`` (three
        numbers) and the other small values travel on the FrameRef (``scale``, ``source_size``: the frame was
        scaled down at capture from a ``source_size`` frame by the whole factor ``scale``)."""
        h, w = image.shape[:2]
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"frames must be H x W x 3 uint8 BGR, got {image.shape} {image.dtype}")
        if h * w > self.spec.capacity_px:
            raise FrameTooLarge(
                f"a {w}x{h} frame does not fit a ring slot of {self.spec.capacity_px} pixels "
                "(pipeline.frame_max_pixels): scale it down first by hal.scale_factor, as the capture stage does")
        has_depth = depth is not None and self._depths is not None
        slot = self._next
        self._next = (self._next + 1) % self.spec.slots
        hdr = self._hdr[slot]
        hdr[0] |= 1                                   # odd: being written (already odd if a writer died here)
        hdr[1:5] = (seq, w, h, int(has_depth))
        self._times[slot] = (t_capture, depth_scale)
        self._images[slot, : h * w * 3] = image.reshape(-1)
        if has_depth:
            self._depths[slot, : h * w] = np.asarray(depth, np.uint16).reshape(-1)
        hdr[0] += 1                                   # even: stable
        return FrameRef(slot=slot, seq=seq, t_capture=t_capture, width=w, height=h, has_depth=has_depth,
                        intrinsics=intrinsics, t_origin=t_origin, gravity=gravity, scale=int(scale),
                        source_size=None if source_size is None else (int(source_size[0]), int(source_size[1])))

    def read(self, ref: FrameRef) -> tuple[np.ndarray, np.ndarray | None, float] | None:
        """Copies of (image, depth or None, depth_scale) of ``ref``, or None if it was overwritten."""
        if not 0 <= ref.slot < self.spec.slots:
            raise ValueError(f"slot {ref.slot} is outside the ring of {self.spec.slots} slots")
        hdr = self._hdr[ref.slot]
        lock = int(hdr[0])
        if lock % 2 or int(hdr[1]) != ref.seq:
            return None
        n = ref.width * ref.height
        image = self._images[ref.slot, : n * 3].copy().reshape(ref.height, ref.width, 3)
        depth = None
        if ref.has_depth and self._depths is not None:
            depth = self._depths[ref.slot, :n].copy().reshape(ref.height, ref.width)
        scale = float(self._times[ref.slot, 1])
        if int(hdr[0]) != lock or int(hdr[1]) != ref.seq:
            return None
        return image, depth, scale

    def close(self) -> None:
        """Detach; the owner (supervisor) also unlinks the segment."""
        self._hdr = self._times = self._images = self._depths = None  # release the buffer views
        shm.release(self._segment, self._owner)
