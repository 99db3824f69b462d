"""Frames larger than the pipeline's working size, scaled down once at capture by a whole factor.

The working size is a number of pixels (``pipeline.frame_max_pixels``: a ring slot), not a width and a height,
so landscape and portrait frames are treated alike. A frame with more pixels is scaled down by the smallest
whole factor ``k`` (2, 3, ...) that brings it within that number: each k x k block of pixels becomes one, the
colour image by area interpolation (OpenCV's ``INTER_AREA``: the mean of the block, no aliasing), the aligned
depth image by nearest neighbour (depth values must not be blended across an object's edge). The last
``width % k`` columns and ``height % k`` rows (fewer than k pixels at the right and bottom edges) are left
out, so a point at ``(x, y)`` of the scaled frame is exactly ``(k x, k y)`` of the original.

A whole factor because it is what makes the cost small: OpenCV averages whole blocks on a fast path
(0.5 ms for 1920x1080 to 960x540 here), while a fractional area resize of the same frame to 1280x720 took
8-12 ms (docs/benchmarks.md, "Frame sizes"). Nothing is dropped for its size below :data:`MAX_DECODE_PIXELS`,
the largest frame a source is asked to decode at all.
"""

from __future__ import annotations

import cv2
import numpy as np

# The largest frame (width x height) a source decodes: 8K UHD, 7680 x 4320 (about 100 MB as BGR). An image
# file above it is skipped unread (its size comes from the file's header), whatever the working size.
MAX_DECODE_PIXELS = 7680 * 4320


def scale_factor(width: int, height: int, max_pixels: int) -> int:
    """The whole factor ``k`` >= 1 by which a ``width`` x ``height`` frame is scaled down to fit
    ``max_pixels``: 1 when it already fits, else the smallest k with (width // k) * (height // k) <= max_pixels."""
    width, height, max_pixels = int(width), int(height), int(max_pixels)
    if width <= 0 or height <= 0:
        raise ValueError(f"a frame of {width}x{height} pixels has no pixels")
    if max_pixels <= 0:
        raise ValueError(f"max_pixels must be positive, got {max_pixels}")
    k = 1
    while (width // k) * (height // k) > max_pixels:
        k += 1
    return k


def working_size(width: int, height: int, max_pixels: int) -> tuple[int, int]:
    """(width, height) of a ``width`` x ``height`` frame once scaled down to fit ``max_pixels``."""
    k = scale_factor(width, height, max_pixels)
    return max(1, int(width) // k), max(1, int(height) // k)


def downscale(image: np.ndarray, k: int) -> np.ndarray:
    """``image`` (H x W x C uint8) scaled down by the whole factor ``k``: the mean of each k x k block."""
    if k == 1:
        return image
    h, w = image.shape[0] // k, image.shape[1] // k
    return cv2.resize(image[: h * k, : w * k], (w, h), interpolation=cv2.INTER_AREA)


def downscale_depth(depth: np.ndarray, k: int) -> np.ndarray:
    """A depth image (H x W uint16) scaled down by the whole factor ``k``: the centre pixel of each block."""
    if k == 1:
        return depth
    h, w = depth.shape[0] // k, depth.shape[1] // k
    return np.ascontiguousarray(depth[k // 2:: k, k // 2:: k][:h, :w])
