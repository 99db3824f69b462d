"""SSD anchors of the BlazePose detector (MediaPipe's ``SsdAnchorsCalculator`` with the pose options).

Options (tech-notes d.3, ``pose_detection_cpu.pbtxt``): 5 layers, strides 8, 16, 32, 32, 32 on a 224×224 input,
anchor offset 0.5, one aspect ratio plus the interpolated scale (2 anchors per cell and layer), fixed anchor
size. Consecutive layers with the same stride share one grid, so the 7×7 grid carries 3 × 2 = 6 anchors per
cell: 28·28·2 + 14·14·2 + 7·7·6 = 2254 anchors.

With ``fixed_anchor_size`` every anchor has width = height = 1, so only the centres matter; they are in
normalized coordinates of the 224×224 detector input (x right, y down).
"""

from __future__ import annotations

import math

import numpy as np

INPUT_SIZE = 224
STRIDES = (8, 16, 32, 32, 32)
ANCHORS_PER_LAYER = 2  # aspect ratio 1.0 + the interpolated-scale anchor
NUM_ANCHORS = 2254


def ssd_anchor_centres(input_size: int = INPUT_SIZE, strides: tuple[int, ...] = STRIDES,
                       anchors_per_layer: int = ANCHORS_PER_LAYER, offset: float = 0.5) -> np.ndarray:
    """Anchor centres, shape (N, 2) float64 ``[x, y]`` normalized to the detector input.

    Order as MediaPipe emits them: layer group (equal consecutive strides merged), then row y, column x,
    then anchor within the cell.
    """
    centres: list[np.ndarray] = []
    layer = 0
    while layer < len(strides):
        stride = strides[layer]
        group = 0
        while layer + group < len(strides) and strides[layer + group] == stride:
            group += 1
        cells = math.ceil(input_size / stride)
        per_cell = group * anchors_per_layer
        ys, xs = np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij")
        xy = np.stack([(xs + offset) / cells, (ys + offset) / cells], axis=-1).reshape(-1, 1, 2)
        centres.append(np.repeat(xy, per_cell, axis=1).reshape(-1, 2))
        layer += group
    return np.concatenate(centres, axis=0)
