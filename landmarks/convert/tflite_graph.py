"""A TFLite flatbuffer read into plain Python values: tensors (shape, dtype, constant data, sparsity) and
operators (name, inputs, outputs, options). Only the first subgraph is read (the pose models have one)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import tflite
from flatbuffers.table import Table

from posed.landmarks.convert.densify import DimMetadata

_DTYPES = {
    tflite.TensorType.FLOAT32: np.dtype("<f4"),
    tflite.TensorType.FLOAT16: np.dtype("<f2"),
    tflite.TensorType.INT32: np.dtype("<i4"),
    tflite.TensorType.UINT8: np.dtype("u1"),
    tflite.TensorType.INT64: np.dtype("<i8"),
    tflite.TensorType.BOOL: np.dtype("?"),
    tflite.TensorType.INT16: np.dtype("<i2"),
    tflite.TensorType.INT8: np.dtype("i1"),
    tflite.TensorType.FLOAT64: np.dtype("<f8"),
}
_TYPE_NAMES = {v: k for k, v in vars(tflite.TensorType).items() if not k.startswith("_")}
OP_NAMES = {v: k for k, v in vars(tflite.BuiltinOperator).items() if not k.startswith("_")}
_INDEX_VECTORS = {
    tflite.SparseIndexVector.Int32Vector: tflite.Int32Vector,
    tflite.SparseIndexVector.Uint16Vector: tflite.Uint16Vector,
    tflite.SparseIndexVector.Uint8Vector: tflite.Uint8Vector,
}


class TFLiteFormatError(ValueError):
    """The file is not a TFLite model this reader understands."""


@dataclass(frozen=True)
class Sparsity:
    traversal_order: tuple[int, ...]
    block_map: tuple[int, ...]
    dim_metadata: tuple[DimMetadata, ...]


@dataclass(frozen=True)
class Tensor:
    index: int
    name: str
    shape: tuple[int, ...]
    dtype: np.dtype
    type_name: str
    data: np.ndarray | None  # constant content, stored layout (sparse: the stored values only)
    sparsity: Sparsity | None
    quantized: bool  # has scale/zero-point quantization parameters


@dataclass(frozen=True)
class Operator:
    index: int
    name: str  # builtin operator name, e.g. "CONV_2D"
    inputs: tuple[int, ...]  # tensor indices, -1 = optional input left out
    outputs: tuple[int, ...]
    options: Any = field(default=None, repr=False)  # the tflite.*Options table, or None


@dataclass(frozen=True)
class Graph:
    tensors: tuple[Tensor, ...]
    operators: tuple[Operator, ...]
    inputs: tuple[int, ...]
    outputs: tuple[int, ...]


def _index_vector(kind: int, table: Table | None, what: str) -> np.ndarray:
    if table is None or kind not in _INDEX_VECTORS:
        raise TFLiteFormatError(f"sparse {what}: unsupported index vector type {kind}")
    vec = _INDEX_VECTORS[kind]()
    vec.Init(table.Bytes, table.Pos)
    return vec.ValuesAsNumpy().astype(np.int64) if vec.ValuesLength() else np.zeros(0, np.int64)


def _sparsity(sp) -> Sparsity:
    metas = []
    for j in range(sp.DimMetadataLength()):
        dm = sp.DimMetadata(j)
        if dm.Format() == tflite.DimensionType.DENSE:
            metas.append(DimMetadata(format=0, dense_size=dm.DenseSize()))
        else:
            metas.append(DimMetadata(
                format=1,
                segments=_index_vector(dm.ArraySegmentsType(), dm.ArraySegments(), "array_segments"),
                indices=_index_vector(dm.ArrayIndicesType(), dm.ArrayIndices(), "array_indices"),
            ))
    order = tuple(int(v) for v in sp.TraversalOrderAsNumpy()) if sp.TraversalOrderLength() else ()
    blocks = tuple(int(v) for v in sp.BlockMapAsNumpy()) if sp.BlockMapLength() else ()
    return Sparsity(order, blocks, tuple(metas))


def _options(op, opname: str):
    """The operator's options table as the matching ``tflite.<Name>Options`` class, or None."""
    table = op.BuiltinOptions()
    if table is None:
        return None
    kind = op.BuiltinOptionsType()
    names = {v: k for k, v in vars(tflite.BuiltinOptions).items() if not k.startswith("_")}
    cls = getattr(tflite, names.get(kind, ""), None)
    if cls is None:
        return None
    obj = cls()
    obj.Init(table.Bytes, table.Pos)
    return obj


def read_graph(buf: bytes) -> Graph:
    """Parse a TFLite flatbuffer (the bytes of a ``.tflite`` file)."""
    if len(buf) < 8 or buf[4:8] != b"TFL3":
        raise TFLiteFormatError("not a TFLite flatbuffer (file identifier TFL3 missing)")
    try:
        model = tflite.Model.GetRootAsModel(buf, 0)
        if model.SubgraphsLength() < 1:
            raise TFLiteFormatError("the model has no subgraph")
        g = model.Subgraphs(0)
        tensors = []
        for i in range(g.TensorsLength()):
            t = g.Tensors(i)
            ttype = t.Type()
            dtype = _DTYPES.get(ttype)
            shape = tuple(int(v) for v in t.ShapeAsNumpy()) if t.ShapeLength() else ()
            data = None
            b = model.Buffers(t.Buffer())
            if b is not None and b.DataLength():
                if dtype is None:
                    raise TFLiteFormatError(f"tensor {t.Name().decode()!r}: constant of unsupported type "
                                            f"{_TYPE_NAMES.get(ttype, ttype)}")
                data = b.DataAsNumpy().view(dtype).copy()
            elif b is not None and b.Size():
                raise TFLiteFormatError(f"tensor {t.Name().decode()!r}: data stored outside the flatbuffer "
                                        "(buffer offset/size, models > 2 GB) is not supported")
            q = t.Quantization()
            quantized = bool(q is not None and q.ScaleLength())
            sparsity = _sparsity(t.Sparsity()) if t.Sparsity() is not None else None
            tensors.append(Tensor(i, t.Name().decode(), shape, dtype, _TYPE_NAMES.get(ttype, str(ttype)),
                                  data, sparsity, quantized))
        operators = []
        for i in range(g.OperatorsLength()):
            op = g.Operators(i)
            oc = model.OperatorCodes(op.OpcodeIndex())
            code = max(oc.BuiltinCode(), oc.DeprecatedBuiltinCode())
            name = OP_NAMES.get(code, f"builtin code {code}")
            if code == tflite.BuiltinOperator.CUSTOM:
                name = f"CUSTOM:{(oc.CustomCode() or b'').decode()}"
            ins = tuple(int(v) for v in op.InputsAsNumpy()) if op.InputsLength() else ()
            outs = tuple(int(v) for v in op.OutputsAsNumpy()) if op.OutputsLength() else ()
            operators.append(Operator(i, name, ins, outs, _options(op, name)))
        inputs = tuple(int(v) for v in g.InputsAsNumpy())
        outputs = tuple(int(v) for v in g.OutputsAsNumpy())
    except TFLiteFormatError:
        raise
    except Exception as exc:  # a truncated or corrupt flatbuffer raises anything from struct/IndexError
        raise TFLiteFormatError(f"corrupt TFLite flatbuffer: {type(exc).__name__}: {exc}") from exc
    return Graph(tuple(tensors), tuple(operators), inputs, outputs)
