"""Sparse TFLite tensors made dense (what the DENSIFY op does at run time, done once at conversion).

TFLite stores a sparse tensor of shape ``dims`` (rank n) as a walk over ``n + k`` "expanded" dimensions:
the n original dimensions (a blocked one counts its blocks) followed by k block dimensions, block j
splitting original dimension ``block_map[j]``. ``traversal_order`` is the order in which the walk visits
the expanded dimensions (outermost first) and ``dim_metadata[i]`` describes the i-th visited one:
DENSE (every index ``0..dense_size-1``) or SPARSE_CSR (for parent position p, the indices
``array_indices[array_segments[p]:array_segments[p+1]]``). The position reached after the last level is
the index of the value in the stored values. Reference: the ``SparsityParameters`` table of TFLite's
``schema.fbs`` (tensorflow/compiler/mlir/lite/schema/schema.fbs).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

DENSE = 0
SPARSE_CSR = 1


@dataclass(frozen=True)
class DimMetadata:
    """One level of the walk: ``format`` DENSE (uses ``dense_size``) or SPARSE_CSR (uses ``segments``,
    ``indices``)."""

    format: int
    dense_size: int = 0
    segments: np.ndarray | None = None
    indices: np.ndarray | None = None


def densify(
    values: np.ndarray,
    dims: Sequence[int],
    traversal_order: Sequence[int],
    block_map: Sequence[int],
    dim_metadata: Sequence[DimMetadata],
) -> np.ndarray:
    """The dense array of shape ``dims`` (zeros where nothing is stored) holding the sparse ``values``.

    Raises ValueError when the sparsity parameters are inconsistent with ``dims`` or ``values``.
    """
    dims = [int(d) for d in dims]
    n, k = len(dims), len(block_map)
    order = [int(t) for t in traversal_order]
    if sorted(order) != list(range(n + k)):
        raise ValueError(f"traversal_order {order} is not a permutation of 0..{n + k - 1}")
    if len(dim_metadata) != n + k:
        raise ValueError(f"{len(dim_metadata)} dim_metadata entries for {n + k} expanded dimensions")
    values = np.asarray(values).reshape(-1)

    positions = np.zeros(1, dtype=np.int64)  # position of each partial path in the enumeration so far
    coords = np.zeros((n + k, 1), dtype=np.int64)  # expanded coordinates of each path, by expanded dim
    for level, meta in enumerate(dim_metadata):
        dim = order[level]
        if meta.format == DENSE:
            size = int(meta.dense_size)
            step = np.arange(size, dtype=np.int64)
            new_positions = (positions[:, None] * size + step[None, :]).reshape(-1)
            coords = np.repeat(coords, size, axis=1)
            coords[dim] = np.tile(step, len(positions))
        elif meta.format == SPARSE_CSR:
            segments = np.asarray(meta.segments, dtype=np.int64)
            indices = np.asarray(meta.indices, dtype=np.int64)
            if positions.size and positions.max() + 1 >= segments.size:
                raise ValueError(f"level {level}: array_segments has {segments.size} entries, "
                                 f"needs {positions.max() + 2}")
            starts, ends = segments[positions], segments[positions + 1]
            counts = ends - starts
            if np.any(counts < 0) or (counts.sum() and ends.max() > indices.size):
                raise ValueError(f"level {level}: array_segments do not fit array_indices ({indices.size})")
            parent = np.repeat(np.arange(len(positions)), counts)
            offsets = np.arange(counts.sum(), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
            new_positions = starts[parent] + offsets
            coords = coords[:, parent]
            coords[dim] = indices[new_positions]
        else:
            raise ValueError(f"level {level}: unknown dimension format {meta.format}")
        positions = new_positions

    if positions.size and positions.max() >= values.size:
        raise ValueError(f"the sparsity walk reaches value {positions.max()} "
                         f"but only {values.size} are stored")

    # Expanded coordinates -> original coordinates (blocked dims: outer * block_size + inner).
    original = coords[:n].copy()
    for j, d in enumerate(block_map):
        size = _block_size(dims, order, dim_metadata, int(d), n + j)
        original[int(d)] = original[int(d)] * size + coords[n + j]
    for d in range(n):
        if original[d].size and (original[d].min() < 0 or original[d].max() >= dims[d]):
            raise ValueError(f"sparse index out of range in dimension {d} (size {dims[d]})")

    dense = np.zeros(dims, dtype=values.dtype)
    dense[tuple(original)] = values[positions]
    return dense


def _block_size(dims: list[int], order: list[int], dim_metadata: Sequence[DimMetadata], d: int,
                block_dim: int) -> int:
    """Size of the blocks splitting original dimension ``d``: the dense size of the level walking the block
    dimension, or (when that level is sparse) ``dims[d]`` over the dense count of blocks."""
    inner = dim_metadata[order.index(block_dim)]
    if inner.format == DENSE:
        return int(inner.dense_size)
    outer = dim_metadata[order.index(d)]
    if outer.format == DENSE and outer.dense_size > 0 and dims[d] % outer.dense_size == 0:
        return dims[d] // int(outer.dense_size)
    raise ValueError(f"cannot tell the block size of dimension {d}: both its levels are sparse")
