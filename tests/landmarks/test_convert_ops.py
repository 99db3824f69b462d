"""Each supported TFLite operator, alone in a tiny hand-built model, converted and run in onnxruntime against
LiteRT's own kernels — including configurations the two pose models do not use (odd sizes, asymmetric SAME
padding, depth multiplier, align_corners, block-sparse weights), and the errors for what is not supported."""

from __future__ import annotations

from dataclasses import dataclass, field

import flatbuffers
import numpy as np
import onnxruntime as ort
import pytest
import tflite
from ai_edge_litert.interpreter import Interpreter, OpResolverType

from posed.landmarks.convert import SUPPORTED_OPS, ConversionError, UnsupportedOperatorError, convert
from posed.landmarks.convert.tflite_graph import TFLiteFormatError

T = tflite.TensorType
OP = tflite.BuiltinOperator
OPT = tflite.BuiltinOptions
ACT = tflite.ActivationFunctionType
SAME, VALID = tflite.Padding.SAME, tflite.Padding.VALID
TFL_TYPES = {np.dtype("float32"): T.FLOAT32, np.dtype("float16"): T.FLOAT16, np.dtype("int32"): T.INT32}


# ---- a minimal TFLite writer ---------------------------------------------------------------------------
@dataclass
class Sparse:
    """Sparsity parameters: per level (format, dense_size, segments, indices)."""

    traversal_order: list[int]
    block_map: list[int]
    levels: list[tuple[int, int, list[int], list[int]]]


@dataclass
class Tensor:
    name: str
    shape: tuple[int, ...]
    dtype: str = "float32"
    data: np.ndarray | None = None  # constant content (sparse: stored values)
    sparse: Sparse | None = None


@dataclass
class Op:
    code: int
    inputs: list[int]
    outputs: list[int]
    options: tuple[int, dict] | None = None  # (BuiltinOptions type, {field: value})
    extra: dict = field(default_factory=dict)


_OPTION_TABLES = {
    OPT.Conv2DOptions: "Conv2DOptions", OPT.DepthwiseConv2DOptions: "DepthwiseConv2DOptions",
    OPT.Pool2DOptions: "Pool2DOptions", OPT.ResizeBilinearOptions: "ResizeBilinearOptions",
    OPT.ConcatenationOptions: "ConcatenationOptions", OPT.DepthToSpaceOptions: "DepthToSpaceOptions",
    OPT.AddOptions: "AddOptions", OPT.ReshapeOptions: "ReshapeOptions", OPT.PadOptions: "PadOptions",
}


def _vec(b: flatbuffers.Builder, values, dtype) -> int:
    return b.CreateNumpyVector(np.asarray(values, dtype=dtype))


def _index_vector(b: flatbuffers.Builder, values: list[int]) -> int:
    data = _vec(b, values, np.int32)
    tflite.Int32VectorStart(b)
    tflite.Int32VectorAddValues(b, data)
    return tflite.Int32VectorEnd(b)


def _sparsity(b: flatbuffers.Builder, sp: Sparse) -> int:
    metas = []
    for fmt, dense_size, segments, indices in sp.levels:
        seg = _index_vector(b, segments) if fmt == 1 else None
        idx = _index_vector(b, indices) if fmt == 1 else None
        tflite.DimensionMetadataStart(b)
        tflite.DimensionMetadataAddFormat(b, fmt)
        tflite.DimensionMetadataAddDenseSize(b, dense_size)
        if fmt == 1:
            tflite.DimensionMetadataAddArraySegmentsType(b, tflite.SparseIndexVector.Int32Vector)
            tflite.DimensionMetadataAddArraySegments(b, seg)
            tflite.DimensionMetadataAddArrayIndicesType(b, tflite.SparseIndexVector.Int32Vector)
            tflite.DimensionMetadataAddArrayIndices(b, idx)
        metas.append(tflite.DimensionMetadataEnd(b))
    order = _vec(b, sp.traversal_order, np.int32)
    blocks = _vec(b, sp.block_map, np.int32)
    tflite.SparsityParametersStartDimMetadataVector(b, len(metas))
    for m in reversed(metas):
        b.PrependUOffsetTRelative(m)
    dim_meta = b.EndVector()
    tflite.SparsityParametersStart(b)
    tflite.SparsityParametersAddTraversalOrder(b, order)
    tflite.SparsityParametersAddBlockMap(b, blocks)
    tflite.SparsityParametersAddDimMetadata(b, dim_meta)
    return tflite.SparsityParametersEnd(b)


def _table_vector(b: flatbuffers.Builder, start, items: list[int]) -> int:
    start(b, len(items))
    for item in reversed(items):
        b.PrependUOffsetTRelative(item)
    return b.EndVector()


def build_tflite(tensors: list[Tensor], ops: list[Op], inputs: list[int], outputs: list[int]) -> bytes:
    b = flatbuffers.Builder(4096)
    buffers, buffer_of = [], []
    tflite.BufferStart(b)
    buffers.append(tflite.BufferEnd(b))  # buffer 0: empty, by convention
    for t in tensors:
        if t.data is None:
            buffer_of.append(0)
            continue
        raw = np.ascontiguousarray(t.data.astype(t.dtype)).view(np.uint8).reshape(-1)
        b.StartVector(1, raw.size, 16)
        b.head -= raw.size
        b.Bytes[b.head:b.head + raw.size] = raw.tobytes()
        data = b.EndVector()
        tflite.BufferStart(b)
        tflite.BufferAddData(b, data)
        buffer_of.append(len(buffers))
        buffers.append(tflite.BufferEnd(b))
    tensor_offsets = []
    for t, buf in zip(tensors, buffer_of, strict=True):
        name = b.CreateString(t.name)
        shape = _vec(b, t.shape, np.int32)
        sparsity = _sparsity(b, t.sparse) if t.sparse else None
        tflite.TensorStart(b)
        tflite.TensorAddShape(b, shape)
        tflite.TensorAddType(b, TFL_TYPES[np.dtype(t.dtype)])
        tflite.TensorAddBuffer(b, buf)
        tflite.TensorAddName(b, name)
        if sparsity is not None:
            tflite.TensorAddSparsity(b, sparsity)
        tensor_offsets.append(tflite.TensorEnd(b))
    codes = sorted({op.code for op in ops})
    op_offsets = []
    for op in ops:
        opts = None
        if op.options is not None:
            kind, values = op.options
            table = _OPTION_TABLES[kind]
            prepared = {k: (_vec(b, v, np.int32) if isinstance(v, list) else v) for k, v in values.items()}
            getattr(tflite, f"{table}Start")(b)
            for key, value in prepared.items():
                getattr(tflite, f"{table}Add{key}")(b, value)
            opts = getattr(tflite, f"{table}End")(b)
        ins, outs = _vec(b, op.inputs, np.int32), _vec(b, op.outputs, np.int32)
        tflite.OperatorStart(b)
        tflite.OperatorAddOpcodeIndex(b, codes.index(op.code))
        tflite.OperatorAddInputs(b, ins)
        tflite.OperatorAddOutputs(b, outs)
        if opts is not None:
            tflite.OperatorAddBuiltinOptionsType(b, op.options[0])
            tflite.OperatorAddBuiltinOptions(b, opts)
        op_offsets.append(tflite.OperatorEnd(b))
    code_offsets = []
    for code in codes:
        tflite.OperatorCodeStart(b)
        tflite.OperatorCodeAddDeprecatedBuiltinCode(b, min(code, 127))
        tflite.OperatorCodeAddBuiltinCode(b, code)
        tflite.OperatorCodeAddVersion(b, 1)
        code_offsets.append(tflite.OperatorCodeEnd(b))
    t_vec = _table_vector(b, tflite.SubGraphStartTensorsVector, tensor_offsets)
    o_vec = _table_vector(b, tflite.SubGraphStartOperatorsVector, op_offsets)
    in_vec, out_vec = _vec(b, inputs, np.int32), _vec(b, outputs, np.int32)
    name = b.CreateString("main")
    tflite.SubGraphStart(b)
    tflite.SubGraphAddTensors(b, t_vec)
    tflite.SubGraphAddInputs(b, in_vec)
    tflite.SubGraphAddOutputs(b, out_vec)
    tflite.SubGraphAddOperators(b, o_vec)
    tflite.SubGraphAddName(b, name)
    subgraph = tflite.SubGraphEnd(b)
    sg_vec = _table_vector(b, tflite.ModelStartSubgraphsVector, [subgraph])
    oc_vec = _table_vector(b, tflite.ModelStartOperatorCodesVector, code_offsets)
    buf_vec = _table_vector(b, tflite.ModelStartBuffersVector, buffers)
    desc = b.CreateString("posed test model")
    tflite.ModelStart(b)
    tflite.ModelAddVersion(b, 3)
    tflite.ModelAddOperatorCodes(b, oc_vec)
    tflite.ModelAddSubgraphs(b, sg_vec)
    tflite.ModelAddDescription(b, desc)
    tflite.ModelAddBuffers(b, buf_vec)
    b.Finish(tflite.ModelEnd(b), file_identifier=b"TFL3")
    return bytes(b.Output())


# ---- running both --------------------------------------------------------------------------------------
def run_litert(model: bytes, feeds: list[np.ndarray]) -> list[np.ndarray]:
    it = Interpreter(model_content=model, experimental_op_resolver_type=OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
    it.allocate_tensors()
    for d, x in zip(it.get_input_details(), feeds, strict=True):
        it.set_tensor(d["index"], x)
    it.invoke()
    return [it.get_tensor(d["index"]).copy() for d in it.get_output_details()]


def run_onnx(model: bytes, feeds: list[np.ndarray]) -> tuple[list[np.ndarray], list[str]]:
    onnx_model = convert(model, "test")
    sess = ort.InferenceSession(onnx_model.SerializeToString(), providers=["CPUExecutionProvider"])
    outs = sess.run(None, {i.name: x for i, x in zip(sess.get_inputs(), feeds, strict=True)})
    return outs, [o.name for o in sess.get_outputs()]


def assert_same(model: bytes, feeds: list[np.ndarray], bounds: list) -> None:
    """onnxruntime against LiteRT, element by element: |onnx - LiteRT| <= the bound of each output (a scalar or
    an array of the output's shape, from the helpers below; 0 = bit-identical)."""
    ref = run_litert(model, feeds)
    got, names = run_onnx(model, feeds)
    assert len(ref) == len(got) == len(bounds)
    for r, g, name, bound in zip(ref, got, names, bounds, strict=True):
        assert g.shape == r.shape, name
        diff = np.abs(g.astype(np.float64) - r.astype(np.float64))
        bound = np.broadcast_to(np.asarray(bound, np.float64), diff.shape)
        over = ~(diff <= bound)  # a NaN is over too
        worst = np.unravel_index(np.argmax(np.where(over, diff, -1.0)), diff.shape)
        assert not over.any(), (f"{name}: {int(over.sum())} of {diff.size} elements differ by more than the "
                                f"rounding bound, e.g. {diff[worst]:.3g} > {bound[worst]:.3g} at {worst}")


# ---- how far apart two float32 implementations may be ---------------------------------------------------
# The bounds are float32 error analysis on the test's own numbers, not a measurement: kernels sum in different
# orders on different CPUs (SIMD width, blocking, FMA), so no fixed tolerance measured on one machine holds.
U32 = 2.0**-24  # float32 unit roundoff


def gamma(k: int) -> float:
    """gamma_k = k u / (1 - k u): a float32 sum of k products, evaluated in any order, with or without FMA, is
    within gamma_k * sum |terms| of the exact value (Higham, Accuracy and Stability of Numerical Algorithms,
    2nd ed., section 3.1)."""
    return k * U32 / (1 - k * U32)


def dot_bound(k: int, magnitude: np.ndarray) -> np.ndarray:
    """|onnx - LiteRT| for outputs that are sums of ``k`` products (a bias counts as one), ``magnitude`` = the sum
    of their absolute values per element (float64): each result is within gamma_k * magnitude of the exact one,
    so the two are within twice that. A fused ReLU, ReLU6 or clamp cannot widen it (1-Lipschitz), and the
    magnitude includes |bias| > 0, so no absolute floor is needed for outputs near 0."""
    return 2.0 * gamma(k) * np.asarray(magnitude, np.float64)


def conv_magnitude(x, w, b, stride, padding, dilation=(1, 1), depthwise=False, mult=1) -> tuple[np.ndarray, int]:
    """(sum |w_i x_i| + |b| per output element, float64, and the number of terms k) of CONV_2D (w: O,KH,KW,I) or
    DEPTHWISE_CONV_2D (w: 1,KH,KW,C*M) with TFLite's SAME padding (the odd pixel after)."""
    ax, aw = np.abs(np.asarray(x, np.float64)), np.abs(np.asarray(w, np.float64))
    _, h, wd, c = ax.shape
    kh, kw = aw.shape[1:3]
    (sh, sw), (dh, dw) = stride, dilation
    if padding == SAME:
        oh, ow = -(-h // sh), -(-wd // sw)
    else:
        oh, ow = (h - (kh - 1) * dh - 1) // sh + 1, (wd - (kw - 1) * dw - 1) // sw + 1
    ph, pw = max((oh - 1) * sh + (kh - 1) * dh + 1 - h, 0), max((ow - 1) * sw + (kw - 1) * dw + 1 - wd, 0)
    xp = np.pad(ax, ((0, 0), (ph // 2, ph - ph // 2), (pw // 2, pw - pw // 2), (0, 0)))
    out = np.abs(np.asarray(b, np.float64))
    for i in range(kh):
        for j in range(kw):
            patch = xp[:, i * dh:i * dh + (oh - 1) * sh + 1:sh, j * dw:j * dw + (ow - 1) * sw + 1:sw, :]
            out = out + (np.repeat(patch, mult, axis=3) * aw[0, i, j] if depthwise else patch @ aw[:, i, j, :].T)
    return out, kh * kw * (1 if depthwise else c) + 1


def resize_bound(x: np.ndarray) -> float:
    """|onnx - LiteRT| for RESIZE_BILINEAR of ``x`` (N,H,W,C). Each output is sum a_i b_j x_ij over a 2x2
    neighbourhood with weights from the fraction f of a source coordinate s = (d + 0.5) * in/out - 0.5 (or
    d * (in - 1)/(out - 1), d * in/out), computed in float32 by each runtime in its own way: three roundings
    of values below the input size, so |s_onnx - s_litert| <= 2 * 4 u * max(H, W) =: 2 delta. An output moves
    with f at most by |x1 - x0| <= 2 max|x| per axis: 2 axes * 2 delta * 2 max|x|. The arithmetic itself: at
    most 16 roundings on each term's way (weights, two products, three sums, with room for other forms such as
    x0 + f (x1 - x0)), and sum |a_i b_j| <= 1.5^2 (LiteRT weights a border pixel 1.25 and -0.25)."""
    m = float(np.abs(x).max())
    delta = 4 * U32 * max(x.shape[1:3])
    return 2.0 * (2.25 * gamma(16) + 4.0 * delta) * m


# Sigmoid is no sum: each runtime approximates it (ORT's MLAS uses the rational approximation of Eigen, whose
# documentation gives a worst case of a few float32 ulps, 4.5 by exhaustive test). Outputs lie in (0, 1), where
# an ulp is at most 2^-24: 8 such steps each (the 4 ulps at 1.0 that bench/convert_equivalence.UNIT_ROUNDING
# treats as unrankable rounding), twice for the two runtimes.
SIGMOID_BOUND = 2 * 8 * U32


RNG = np.random.default_rng(7)


def rand(*shape, scale=1.0, dtype=np.float32):
    return (RNG.standard_normal(shape) * scale).astype(dtype)


def conv_model(x_shape, w_shape, stride, padding, act, dilation=(1, 1), bias=True, depthwise=False, mult=1,
               w=None, b=None):
    n, h, wd, c = x_shape
    kh, kw = w_shape[1:3]
    if padding == SAME:
        oh, ow = -(-h // stride[0]), -(-wd // stride[1])
    else:
        oh = (h - (kh - 1) * dilation[0] - 1) // stride[0] + 1
        ow = (wd - (kw - 1) * dilation[1] - 1) // stride[1] + 1
    oc = w_shape[3] if depthwise else w_shape[0]
    tensors = [Tensor("x", x_shape), Tensor("w", w_shape, data=rand(*w_shape) if w is None else w),
               Tensor("b", (oc,), data=rand(oc) if b is None else b), Tensor("y", (n, oh, ow, oc))]
    opts = {"Padding": padding, "StrideH": stride[0], "StrideW": stride[1], "FusedActivationFunction": act,
            "DilationHFactor": dilation[0], "DilationWFactor": dilation[1]}
    if depthwise:
        opts["DepthMultiplier"] = mult
    kind = OPT.DepthwiseConv2DOptions if depthwise else OPT.Conv2DOptions
    code = OP.DEPTHWISE_CONV_2D if depthwise else OP.CONV_2D
    ins = [0, 1, 2] if bias else [0, 1, -1]
    return build_tflite(tensors, [Op(code, ins, [3], (kind, opts))], [0], [3])


# ---- operators -----------------------------------------------------------------------------------------
# (LiteRT's float CONV_2D requires the bias input, so every case has one.)
@pytest.mark.parametrize("x_shape, k, stride, padding, act, dilation, bias", [
    ((1, 7, 9, 3), 3, (2, 2), SAME, ACT.RELU6, (1, 1), True),     # odd sizes: asymmetric SAME pads
    ((1, 8, 8, 4), 5, (2, 2), SAME, ACT.NONE, (1, 1), True),      # even size, big kernel
    ((1, 9, 6, 2), 3, (1, 2), SAME, ACT.RELU, (2, 2), True),      # dilation
    ((1, 9, 9, 3), 3, (2, 2), VALID, ACT.RELU_N1_TO_1, (1, 1), True),
    ((1, 6, 5, 3), 1, (1, 1), SAME, ACT.NONE, (1, 1), True),
])
def test_conv_2d(x_shape, k, stride, padding, act, dilation, bias):
    w, b, x = rand(5, k, k, x_shape[3]), rand(5), rand(*x_shape)
    model = conv_model(x_shape, w.shape, stride, padding, act, dilation, bias, w=w, b=b)
    magnitude, terms = conv_magnitude(x, w, b, stride, padding, dilation)
    assert_same(model, [x], [dot_bound(terms, magnitude)])


@pytest.mark.parametrize("x_shape, k, stride, padding, mult", [
    ((1, 7, 9, 3), 3, (2, 2), SAME, 1),
    ((1, 8, 8, 4), 3, (2, 2), SAME, 2),  # depth multiplier: output channel c*M+m reads input channel c
    ((1, 10, 7, 2), 5, (1, 1), VALID, 3),
])
def test_depthwise_conv_2d(x_shape, k, stride, padding, mult):
    c = x_shape[3]
    w, b, x = rand(1, k, k, c * mult), rand(c * mult), rand(*x_shape, scale=2.0)
    model = conv_model(x_shape, w.shape, stride, padding, ACT.RELU6, depthwise=True, mult=mult, w=w, b=b)
    magnitude, terms = conv_magnitude(x, w, b, stride, padding, depthwise=True, mult=mult)
    assert_same(model, [x], [dot_bound(terms, magnitude)])


@pytest.mark.parametrize("padding, k, stride, shape", [
    (SAME, 3, 2, (1, 7, 7, 3)), (VALID, 2, 2, (1, 8, 6, 2)), (SAME, 2, 2, (1, 8, 8, 4))])
def test_max_pool_2d(padding, k, stride, shape):
    n, h, w, c = shape
    oh, ow = (-(-h // stride), -(-w // stride)) if padding == SAME else ((h - k) // stride + 1, (w - k) // stride + 1)
    opts = {"Padding": padding, "StrideH": stride, "StrideW": stride, "FilterHeight": k, "FilterWidth": k,
            "FusedActivationFunction": ACT.NONE}
    model = build_tflite([Tensor("x", shape), Tensor("y", (n, oh, ow, c))],
                         [Op(OP.MAX_POOL_2D, [0], [1], (OPT.Pool2DOptions, opts))], [0], [1])
    # a maximum selects one input value: bit-identical. Negative values: padding must not count as zero.
    assert_same(model, [rand(*shape) - 3.0], [0.0])


@pytest.mark.parametrize("align, half, size", [
    (False, True, (10, 14)), (True, False, (10, 14)), (False, False, (10, 14)),
    (False, True, (3, 4)), (True, False, (3, 9)), (False, False, (7, 3))])
def test_resize_bilinear(align, half, size):
    shape = (1, 5, 7, 3)
    model = build_tflite(
        [Tensor("x", shape), Tensor("size", (2,), "int32", np.array(size, np.int32)),
         Tensor("y", (1, *size, 3))],
        [Op(OP.RESIZE_BILINEAR, [0, 1], [2],
            (OPT.ResizeBilinearOptions, {"AlignCorners": align, "HalfPixelCenters": half}))], [0], [2])
    x = rand(*shape)
    assert_same(model, [x], [resize_bound(x)])


def test_reshape_keeps_tflite_element_order_and_feeds_a_conv():
    # [1,4,6,2] -> [1,2,12,2] (a 4-D reshape that mixes H and W) -> conv: layout must follow NHWC order.
    w, b, x = rand(3, 1, 1, 2), rand(3), rand(1, 4, 6, 2)
    tensors = [Tensor("x", (1, 4, 6, 2)), Tensor("s", (4,), "int32", np.array([1, 2, 12, 2], np.int32)),
               Tensor("r", (1, 2, 12, 2)), Tensor("w", (3, 1, 1, 2), data=w), Tensor("y", (1, 2, 12, 3)),
               Tensor("s2", (2,), "int32", np.array([-1, 6], np.int32)), Tensor("z", (12, 6)),
               Tensor("bias", (3,), data=b)]
    conv = {"Padding": SAME, "StrideH": 1, "StrideW": 1, "FusedActivationFunction": 0,
            "DilationHFactor": 1, "DilationWFactor": 1}
    ops = [Op(OP.RESHAPE, [0, 1], [2]), Op(OP.CONV_2D, [2, 3, 7], [4], (OPT.Conv2DOptions, conv)),
           Op(OP.RESHAPE, [4, 5], [6])]
    magnitude, terms = conv_magnitude(x.reshape(1, 2, 12, 2), w, b, (1, 1), SAME)  # NHWC order = C order
    assert_same(build_tflite(tensors, ops, [0], [6, 2]), [x], [dot_bound(terms, magnitude).reshape(12, 6), 0.0])


@pytest.mark.parametrize("axis", [3, 1, 2, -1])
def test_concatenation_4d(axis):
    a, b = (1, 3, 4, 2), (1, 3, 4, 2)
    out = list(a)
    out[axis] = a[axis] * 2
    w, bias, xa, xb = rand(2, 1, 1, 2), rand(2), rand(*a), rand(*b)
    conv = {"Padding": SAME, "StrideH": 1, "StrideW": 1, "FusedActivationFunction": 0,
            "DilationHFactor": 1, "DilationWFactor": 1}
    tensors = [Tensor("a", a), Tensor("b0", b), Tensor("w", (2, 1, 1, 2), data=w), Tensor("b", b),
               Tensor("y", tuple(out)), Tensor("bias", (2,), data=bias)]
    ops = [Op(OP.CONV_2D, [1, 2, 5], [3], (OPT.Conv2DOptions, conv)),  # one input arrives in NCHW
           Op(OP.CONCATENATION, [0, 3], [4],
              (OPT.ConcatenationOptions, {"Axis": axis, "FusedActivationFunction": ACT.NONE}))]
    magnitude, terms = conv_magnitude(xb, w, bias, (1, 1), SAME)
    bound = np.concatenate([np.zeros(a), dot_bound(terms, magnitude)], axis=axis)  # the copied half: exact
    assert_same(build_tflite(tensors, ops, [0, 1], [4]), [xa, xb], [bound])


def test_concatenation_3d_after_reshape():
    tensors = [Tensor("a", (1, 2, 2, 6)), Tensor("b", (1, 1, 1, 9)), Tensor("s", (3,), "int32",
               np.array([1, -1, 3], np.int32)), Tensor("ra", (1, 8, 3)), Tensor("rb", (1, 3, 3)),
               Tensor("y", (1, 11, 3))]
    ops = [Op(OP.RESHAPE, [0, 2], [3]), Op(OP.RESHAPE, [1, 2], [4]),
           Op(OP.CONCATENATION, [3, 4], [5], (OPT.ConcatenationOptions, {"Axis": 1}))]
    assert_same(build_tflite(tensors, ops, [0, 1], [5]), [rand(1, 2, 2, 6), rand(1, 1, 1, 9)], [0.0])  # copies


def test_depth_to_space():
    model = build_tflite([Tensor("x", (1, 3, 4, 8)), Tensor("y", (1, 6, 8, 2))],
                         [Op(OP.DEPTH_TO_SPACE, [0], [1], (OPT.DepthToSpaceOptions, {"BlockSize": 2}))], [0], [1])
    x = np.arange(96, dtype=np.float32).reshape(1, 3, 4, 8)
    assert_same(model, [x], [0.0])  # moves data only: bit-identical


def test_pad_asymmetric_including_channels():
    pads = np.array([[0, 0], [1, 2], [0, 3], [2, 1]], np.int32)
    model = build_tflite([Tensor("x", (1, 3, 4, 2)), Tensor("p", (4, 2), "int32", pads), Tensor("y", (1, 6, 7, 5))],
                         [Op(OP.PAD, [0, 1], [2])], [0], [2])
    assert_same(model, [rand(1, 3, 4, 2)], [0.0])  # moves data only: bit-identical


def test_add_broadcast_constant_and_logistic():
    tensors = [Tensor("x", (1, 3, 4, 5)), Tensor("c", (5,), data=rand(5)), Tensor("s", (1, 3, 4, 5)),
               Tensor("y", (1, 3, 4, 5)), Tensor("z", (1, 3, 4, 5))]
    ops = [Op(OP.ADD, [0, 1], [2], (OPT.AddOptions, {"FusedActivationFunction": ACT.RELU6})),
           Op(OP.ADD, [2, 0], [3], (OPT.AddOptions, {"FusedActivationFunction": ACT.NONE})),
           Op(OP.LOGISTIC, [3], [4])]
    # y = relu6(x + c) + x: two IEEE additions, each correctly rounded, so both runtimes give the same float32
    # (as one Add in test_selected_outputs_drop_the_operators_only_the_others_need); z = sigmoid(y) differs only
    # by the two sigmoid approximations.
    assert_same(build_tflite(tensors, ops, [0], [4, 3]), [rand(1, 3, 4, 5, scale=3.0)], [SIGMOID_BOUND, 0.0])


def _csr(dense: np.ndarray):
    """Row-major CSR of a 2-D array: segments, indices, values."""
    segments, indices, values = [0], [], []
    for row in dense:
        nz = np.flatnonzero(row)
        indices += nz.tolist()
        values += row[nz].tolist()
        segments.append(len(indices))
    return segments, indices, np.array(values)


def test_densify_and_dequantize_feed_a_conv():
    """Like the detector: sparse float16 1x1 filter -> DENSIFY -> DEQUANTIZE -> CONV_2D."""
    w, bias, x = rand(6, 1, 1, 8), rand(6), rand(1, 4, 4, 8)
    w[np.abs(w) < 0.8] = 0
    segments, indices, values = _csr(w.reshape(6, 8))
    sparse = Sparse([0, 1, 2, 3], [], [(0, 6, [], []), (0, 1, [], []), (0, 1, [], []), (1, 0, segments, indices)])
    conv = {"Padding": SAME, "StrideH": 1, "StrideW": 1, "FusedActivationFunction": 0,
            "DilationHFactor": 1, "DilationWFactor": 1}
    tensors = [Tensor("x", (1, 4, 4, 8)), Tensor("ws", (6, 1, 1, 8), "float16", values.astype(np.float16), sparse),
               Tensor("wd16", (6, 1, 1, 8), "float16"), Tensor("w32", (6, 1, 1, 8)), Tensor("y", (1, 4, 4, 6)),
               Tensor("bias", (6,), data=bias)]
    ops = [Op(OP.DENSIFY, [1], [2]), Op(OP.DEQUANTIZE, [2], [3]),
           Op(OP.CONV_2D, [0, 3, 5], [4], (OPT.Conv2DOptions, conv))]
    magnitude, terms = conv_magnitude(x, w.astype(np.float16), bias, (1, 1), SAME)  # float16 -> 32 is exact
    assert_same(build_tflite(tensors, ops, [0], [4]), [x], [dot_bound(terms, magnitude)])


def test_block_sparse_weights_match_litert():
    """A 1x4-block sparse filter (block_map on the input-channel axis), float32, densified."""
    o, i, bs = 4, 8, 4
    w = rand(o, 1, 1, i)
    w.reshape(o, i // bs, bs)[[0, 1, 2, 3], [1, 0, 0, 1]] = 0  # drop one block per row
    blocks = w.reshape(o, i // bs, bs)
    segments, indices, values = [0], [], []
    for r in range(o):
        for c in range(i // bs):
            if np.any(blocks[r, c]):
                indices.append(c)
                values.extend(blocks[r, c].tolist())
        segments.append(len(indices))
    # expanded dims: 0..3 = O, H, W, I/4 blocks; 4 = the block of I; walk O, H, W, I-blocks (CSR), block.
    sparse = Sparse([0, 1, 2, 3, 4], [3],
                    [(0, o, [], []), (0, 1, [], []), (0, 1, [], []), (1, 0, segments, indices), (0, bs, [], [])])
    conv = {"Padding": VALID, "StrideH": 1, "StrideW": 1, "FusedActivationFunction": 0,
            "DilationHFactor": 1, "DilationWFactor": 1}
    tensors = [Tensor("x", (1, 3, 3, i)), Tensor("ws", (o, 1, 1, i), data=np.array(values, np.float32),
                                                 sparse=sparse),
               Tensor("wd", (o, 1, 1, i)), Tensor("y", (1, 3, 3, o)), Tensor("bias", (o,), data=np.zeros(o))]
    ops = [Op(OP.DENSIFY, [1], [2]), Op(OP.CONV_2D, [0, 2, 4], [3], (OPT.Conv2DOptions, conv))]
    model = build_tflite(tensors, ops, [0], [3])
    x = rand(1, 3, 3, i)
    magnitude, terms = conv_magnitude(x, w, np.zeros(o), (1, 1), VALID)
    assert_same(model, [x], [dot_bound(terms, magnitude)])
    # against the dense product in float64: onnxruntime is within gamma_k of it, the float64 sum within 2^-29 of
    # that, so twice gamma_k covers both
    exact = np.einsum("nhwi,oi->nhwo", x.astype(np.float64), w[:, 0, 0].astype(np.float64))
    assert np.all(np.abs(run_onnx(model, [x])[0][0] - exact) <= dot_bound(terms, magnitude))


# ---- output selection -------------------------------------------------------------------------------
def _two_heads():
    """x -> ADD c -> y (head 1); x -> TANH -> LOGISTIC -> z (head 2, with an operator posed cannot convert)."""
    tensors = [Tensor("x", (1, 4)), Tensor("c", (4,), data=rand(4)), Tensor("y", (1, 4)), Tensor("t", (1, 4)),
               Tensor("z", (1, 4)), Tensor("w", (4,), data=rand(4))]
    ops = [Op(OP.ADD, [0, 1], [2], (OPT.AddOptions, {"FusedActivationFunction": ACT.NONE})),
           Op(OP.TANH, [0], [3]), Op(OP.ADD, [3, 5], [4], (OPT.AddOptions, {"FusedActivationFunction": ACT.NONE}))]
    return build_tflite(tensors, ops, [0], [2, 4])


def test_selected_outputs_drop_the_operators_only_the_others_need():
    model = _two_heads()
    with pytest.raises(UnsupportedOperatorError, match="TANH"):
        convert(model, "two_heads")  # all outputs: the TANH head is needed
    onnx_model = convert(model, "two_heads", outputs=["y"])
    assert [o.name for o in onnx_model.graph.output] == ["y"]
    assert [n.op_type for n in onnx_model.graph.node] == ["Add", "Identity"]
    assert len(onnx_model.graph.initializer) == 1  # w fed only the dropped head
    x = rand(1, 4)
    sess = ort.InferenceSession(onnx_model.SerializeToString(), providers=["CPUExecutionProvider"])
    np.testing.assert_allclose(sess.run(None, {"x": x})[0], run_litert(model, [x])[0], atol=0)


@pytest.mark.parametrize("outputs", [["nope"], ["y", "Identity_9"], []])
def test_selecting_an_unknown_output_lists_the_model_outputs(outputs):
    with pytest.raises(ConversionError, match=r"two_heads: cannot select output.*the model's outputs are y, z"):
        convert(_two_heads(), "two_heads", outputs=outputs)


# ---- what is not supported -----------------------------------------------------------------------------
def test_unknown_operator_is_named_with_the_model():
    model = build_tflite([Tensor("x", (1, 4)), Tensor("y", (1, 4)), Tensor("z", (1, 4))],
                         [Op(OP.TANH, [0], [1]), Op(OP.LOGISTIC, [1], [2])], [0], [2])
    assert run_litert(model, [rand(1, 4)])[0].shape == (1, 4)  # a valid model, just not supported
    with pytest.raises(UnsupportedOperatorError) as err:
        convert(model, "tiny_tanh_model")
    assert "TANH" in str(err.value) and "tiny_tanh_model" in str(err.value)
    assert "LOGISTIC" not in str(err.value).split("supports")[0]


@pytest.mark.parametrize("act", [ACT.TANH, ACT.SIGN_BIT])
def test_unsupported_fused_activation_is_named(act):
    # LiteRT's float CONV_2D silently ignores a fused TANH; the converter refuses rather than guess.
    model = conv_model((1, 4, 4, 2), (2, 1, 1, 2), (1, 1), SAME, act)
    with pytest.raises(ValueError, match=rf"m1: operator #0 CONV_2D: fused activation {act} is not supported"):
        convert(model, "m1")


def test_supported_ops_are_exactly_those_of_the_pose_models(models_dir):
    from posed.landmarks.convert.tflite_graph import read_graph

    used = set()
    for name in ("pose_detection.tflite", "pose_landmark_full.tflite"):
        used |= {op.name for op in read_graph((models_dir / name).read_bytes()).operators}
    assert used == set(SUPPORTED_OPS)


@pytest.mark.parametrize("damage", ["truncate", "identifier", "empty"])
def test_corrupt_flatbuffer_is_reported(models_dir, damage):
    data = (models_dir / "pose_detection.tflite").read_bytes()
    bad = {"truncate": data[:4000], "identifier": data[:4] + b"XXXX" + data[8:], "empty": b""}[damage]
    with pytest.raises(TFLiteFormatError):
        convert(bad, "pose_detection")
