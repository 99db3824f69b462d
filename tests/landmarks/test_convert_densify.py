"""Densifying TFLite sparse tensors: hand-written examples with known dense results, and every sparse tensor
of the real detector against what LiteRT's own DENSIFY kernel produces."""

from __future__ import annotations

import numpy as np
import pytest
from ai_edge_litert.interpreter import Interpreter, OpResolverType

from posed.landmarks.convert.densify import DENSE, SPARSE_CSR, DimMetadata, densify
from posed.landmarks.convert.tflite_graph import read_graph


def D(size):  # a DENSE level, as in the schema
    return DimMetadata(DENSE, dense_size=size)


def S(segments, indices):  # a SPARSE_CSR level
    return DimMetadata(SPARSE_CSR, segments=np.array(segments), indices=np.array(indices))


def test_csr_matrix():
    # [[0, 5, 0, 0],      row 0: col 1
    #  [0, 0, 0, 0],      row 1: nothing
    #  [7, 0, 0, 9]]      row 2: cols 0, 3
    dense = densify(np.array([5.0, 7.0, 9.0]), (3, 4), [0, 1], [], [D(3), S([0, 1, 1, 3], [1, 0, 3])])
    np.testing.assert_array_equal(dense, [[0, 5, 0, 0], [0, 0, 0, 0], [7, 0, 0, 9]])


def test_column_major_traversal():
    # The same matrix stored by columns (traversal_order [1, 0]: columns outer, rows inner).
    dense = densify(np.array([7.0, 5.0, 9.0]), (3, 4), [1, 0], [], [D(4), S([0, 1, 2, 2, 3], [2, 0, 2])])
    np.testing.assert_array_equal(dense, [[0, 5, 0, 0], [0, 0, 0, 0], [7, 0, 0, 9]])


def test_sparse_outer_dimension():
    # Android NNAPI's DENSIFY test case 4 (3x2x2, formats sparse/dense/sparse), dense result from that spec.
    dense = densify(np.array([6.0, 9.0, 8.0, 5.0, 7.0]), (3, 2, 2), [0, 1, 2], [],
                    [S([0, 2], [0, 2]), D(2), S([0, 1, 3, 4, 5], [0, 0, 1, 0, 1])])
    np.testing.assert_array_equal(dense.reshape(-1), [6, 0, 9, 8, 0, 0, 0, 0, 5, 0, 0, 7])


def test_dense_blocks_in_a_sparse_block_row():
    # NNAPI DENSIFY case 3: 4x8 in 2x2 blocks, block columns sparse, blocks walked column-major.
    values = np.array([1, 1, 0, 0, 2, 2, 3, 3, 0, 0, 4, 4, 5, 0, 0, 0], dtype=np.float32)
    dense = densify(values, (4, 8), [0, 1, 3, 2], [0, 1], [D(2), S([0, 3, 4], [0, 1, 2, 1]), D(2), D(2)])
    expected = [1, 0, 2, 3, 0, 4, 0, 0, 1, 0, 2, 3, 0, 4, 0, 0] + [0, 0, 5, 0] + [0] * 12
    np.testing.assert_array_equal(dense.reshape(-1), expected)


def test_sparse_inside_blocks():
    # NNAPI DENSIFY case 8: 10x21 in 5x7 blocks, the in-block dimensions sparse.
    dense = densify(np.array([11.0, 13.0, 17.0, 19.0]), (10, 21), [0, 1, 2, 3], [0, 1],
                    [D(2), D(3), S([0, 1, 2, 3, 4, 4, 4], [1, 2, 3, 1]), S([0, 1, 2, 3, 4], [1, 2, 3, 3])])
    expected = np.zeros(210)
    expected[[22, 51, 80, 129]] = [11, 13, 17, 19]
    np.testing.assert_array_equal(dense.reshape(-1), expected)


def test_keeps_dtype_and_zero_fills():
    dense = densify(np.array([1.5, -2.0], np.float16), (2, 3), [0, 1], [], [D(2), S([0, 1, 2], [2, 0])])
    assert dense.dtype == np.float16
    np.testing.assert_array_equal(dense, [[0, 0, 1.5], [-2.0, 0, 0]])


@pytest.mark.parametrize("args, message", [
    (((2, 2), [0, 0], [], [D(2), D(2)]), "not a permutation"),
    (((2, 2), [0, 1], [], [D(2)]), "dim_metadata entries"),
    (((2, 2), [0, 1], [], [D(2), S([0, 1], [0])]), "array_segments has 2 entries"),
    (((2, 2), [0, 1], [], [D(2), S([0, 1, 2], [0, 5])]), "out of range in dimension 1"),
    (((2, 2), [0, 1], [], [D(2), S([0, 2, 4], [0, 1, 0, 1])]), "only 3 are stored"),
])
def test_inconsistent_parameters_are_refused(args, message):
    with pytest.raises(ValueError, match=message):
        densify(np.array([1.0, 2.0, 3.0]), *args)


def test_every_sparse_tensor_of_the_detector_matches_litert(models_dir):
    """LiteRT's DENSIFY kernel output (kept with experimental_preserve_all_tensors) for the 38 sparse
    filters of pose_detection.tflite equals ours, bit for bit."""
    path = models_dir / "pose_detection.tflite"
    graph = read_graph(path.read_bytes())
    it = Interpreter(model_path=str(path), experimental_preserve_all_tensors=True,
                     experimental_op_resolver_type=OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
    it.allocate_tensors()
    it.set_tensor(it.get_input_details()[0]["index"], np.zeros((1, 224, 224, 3), np.float32))
    it.invoke()
    checked = 0
    for op in graph.operators:
        if op.name != "DENSIFY":
            continue
        src = graph.tensors[op.inputs[0]]
        sp = src.sparsity
        ours = densify(src.data, src.shape, sp.traversal_order, sp.block_map, sp.dim_metadata)
        theirs = it.get_tensor(op.outputs[0])
        assert ours.dtype == theirs.dtype and ours.shape == theirs.shape, src.name
        np.testing.assert_array_equal(ours, theirs, err_msg=src.name)
        assert np.count_nonzero(ours) == src.data.size or np.count_nonzero(src.data) < src.data.size
        checked += 1
    assert checked == 38
