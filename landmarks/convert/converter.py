"""TFLite -> ONNX for MediaPipe's pose models (``pose_detection.tflite``, ``pose_landmark_full.tflite``).

Supports exactly the operators those two models contain: CONV_2D, DEPTHWISE_CONV_2D, ADD, PAD, MAX_POOL_2D,
RESIZE_BILINEAR, RESHAPE, CONCATENATION, DEPTH_TO_SPACE, LOGISTIC, and DEQUANTIZE (float16 weights) /
DENSIFY (sparse weights), which are folded into float32 constants. Inputs and outputs keep their TFLite
names, shapes (NHWC) and element order; inside, rank-4 activations run in NCHW (see ``onnx_graph``).

``outputs`` selects which TFLite outputs the ONNX model computes; operators that feed none of them are left
out. posed converts the landmark model without its segmentation head (``Identity_2``, a 256×256 person mask
the pipeline never reads), which is about 45% of the model's time on a CPU (docs/models.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection

import numpy as np
import onnx
import tflite
from onnx import helper

from posed.landmarks.convert.densify import densify
from posed.landmarks.convert.onnx_graph import NCHW, NHWC, TO_NCHW, OnnxGraph, value_info
from posed.landmarks.convert.tflite_graph import Graph, Operator, Tensor, read_graph
from posed.landmarks.model_pins import CONVERTER_VERSION

# CONVERTER_VERSION (above): this converter's version, kept in one place with the models it was validated with
# (landmarks.model_pins; 2: outputs can be selected, unused operators are pruned): bump it there

OPSET = 17
IR_VERSION = 8  # onnxruntime >= 1.14 reads it
NHWC_AXIS_TO_NCHW = {0: 0, 1: 2, 2: 3, 3: 1}


class ConversionError(ValueError):
    """The model cannot be converted; the message names the model and what is wrong."""


class UnsupportedOperatorError(ConversionError):
    """The model uses an operator this converter does not implement."""


def select_outputs(graph: Graph, outputs: Collection[str] | None, model_name: str) -> tuple[int, ...]:
    """Tensor indices of the requested graph outputs, in the graph's order (all when ``outputs`` is None)."""
    if outputs is None:
        return graph.outputs
    names = {graph.tensors[i].name: i for i in graph.outputs}
    unknown = sorted(set(outputs) - names.keys())
    if unknown or not outputs:
        raise ConversionError(f"{model_name}: cannot select output(s) {unknown or '(none)'}; "
                              f"the model's outputs are {', '.join(names)}")
    return tuple(i for i in graph.outputs if graph.tensors[i].name in outputs)


def needed_operators(graph: Graph, outputs: tuple[int, ...]) -> tuple[Operator, ...]:
    """The operators that contribute to ``outputs`` (tensor indices), in graph order."""
    needed = set(outputs)
    keep = []
    for op in reversed(graph.operators):
        if needed.intersection(op.outputs):
            keep.append(op)
            needed.update(i for i in op.inputs if i >= 0)
    return tuple(reversed(keep))


class _Converter:
    def __init__(self, graph: Graph, model_name: str, outputs: Collection[str] | None = None) -> None:
        self.g = graph
        self.model_name = model_name
        self.outputs = select_outputs(graph, outputs, model_name)
        self.operators = needed_operators(graph, self.outputs)
        self.out = OnnxGraph()
        self.consts: dict[int, np.ndarray] = {}  # tensor index -> constant, TFLite layout, dense
        self.const_values: dict[tuple[int, str], str] = {}  # (tensor index, layout) -> initializer name
        for t in graph.tensors:
            if t.data is not None and t.sparsity is None:
                self.consts[t.index] = t.data.reshape(t.shape) if t.shape else t.data.reshape(())

    # ---- helpers -----------------------------------------------------------------------------------
    def fail(self, op: Operator, msg: str) -> ConversionError:
        return ConversionError(f"{self.model_name}: operator #{op.index} {op.name}: {msg}")

    def tensor(self, index: int) -> Tensor:
        return self.g.tensors[index]

    def const(self, op: Operator, index: int, what: str) -> np.ndarray:
        if index not in self.consts:
            raise self.fail(op, f"{what} ({self.tensor(index).name!r}) must be a constant")
        return self.consts[index]

    def input(self, op: Operator, index: int, layout: str) -> str:
        """ONNX value for input tensor ``index`` in ``layout`` (constants become initializers)."""
        if self.out.has(index):
            return self.out.value(index, layout)
        if index in self.consts:
            if (index, layout) not in self.const_values:
                array = self.consts[index]
                if array.dtype != np.float32:
                    raise self.fail(op, f"constant input {self.tensor(index).name!r} has type {array.dtype}, "
                                        "expected float32")
                if layout == NCHW:  # NHWC broadcasting rules -> the same broadcast in NCHW
                    array = array.reshape((1,) * (4 - array.ndim) + array.shape).transpose(TO_NCHW)
                self.const_values[index, layout] = self.out.constant(array, f"c{index}")
            return self.const_values[index, layout]
        raise self.fail(op, f"input {self.tensor(index).name!r} is neither computed nor constant")

    def rank(self, index: int) -> int:
        return len(self.tensor(index).shape)

    def activation(self, op: Operator, x: str, fused: int) -> str:
        kind = tflite.ActivationFunctionType
        if fused == kind.NONE:
            return x
        if fused == kind.RELU:
            return self.out.node("Relu", [x], f"{x}_relu")
        if fused in (kind.RELU6, kind.RELU_N1_TO_1):
            lo, hi = (0.0, 6.0) if fused == kind.RELU6 else (-1.0, 1.0)
            bounds = [self.out.constant(np.array(v, np.float32), "clip_bound") for v in (lo, hi)]
            return self.out.node("Clip", [x, *bounds], f"{x}_clip")
        # TANH / SIGN_BIT: LiteRT's float kernels do not apply them as fused activations; refuse.
        raise self.fail(op, f"fused activation {fused} is not supported "
                            "(NONE, RELU, RELU_N1_TO_1, RELU6 are)")

    def same_pads(self, op: Operator, in_hw: tuple[int, int], kernel: tuple[int, int],
                  strides: tuple[int, int], dilations: tuple[int, int], padding: int) -> list[int]:
        """ONNX pads [top, left, bottom, right] for TFLite SAME/VALID (SAME puts the odd pixel at the end)."""
        if padding == tflite.Padding.VALID:
            return [0, 0, 0, 0]
        if padding != tflite.Padding.SAME:
            raise self.fail(op, f"padding mode {padding} is not supported")
        begin, end = [], []
        for size, k, s, d in zip(in_hw, kernel, strides, dilations, strict=True):
            out = math.ceil(size / s)
            total = max((out - 1) * s + (k - 1) * d + 1 - size, 0)
            begin.append(total // 2)
            end.append(total - total // 2)
        return begin + end

    def emit(self, op: Operator, name: str, layout: str) -> None:
        self.out.bind(op.outputs[0], name, layout)

    # ---- operators ---------------------------------------------------------------------------------
    def op_DEQUANTIZE(self, op: Operator) -> None:
        src = self.tensor(op.inputs[0])
        if src.quantized or src.dtype != np.float16:
            raise self.fail(op, f"only float16 weights can be dequantized (got {src.type_name}"
                                f"{' with scale/zero-point' if src.quantized else ''})")
        self.consts[op.outputs[0]] = self.const(op, op.inputs[0], "the float16 weights").astype(np.float32)

    def op_DENSIFY(self, op: Operator) -> None:
        src = self.tensor(op.inputs[0])
        if src.sparsity is None or src.data is None:
            raise self.fail(op, f"input {src.name!r} is not a constant sparse tensor")
        sp = src.sparsity
        try:
            self.consts[op.outputs[0]] = densify(src.data, src.shape, sp.traversal_order, sp.block_map,
                                                 sp.dim_metadata)
        except ValueError as exc:
            raise self.fail(op, f"sparse tensor {src.name!r}: {exc}") from exc

    def _conv(self, op: Operator, weights: np.ndarray, group: int, opts) -> None:
        x_t = self.tensor(op.inputs[0])
        if self.rank(op.inputs[0]) != 4:
            raise self.fail(op, f"input rank {self.rank(op.inputs[0])}, expected 4")
        x = self.input(op, op.inputs[0], NCHW)
        strides = (opts.StrideH(), opts.StrideW())
        dilations = (opts.DilationHFactor(), opts.DilationWFactor())
        kernel = weights.shape[2:]
        pads = self.same_pads(op, x_t.shape[1:3], kernel, strides, dilations, opts.Padding())
        inputs = [x, self.out.constant(weights.astype(np.float32), f"w{op.index}")]
        if len(op.inputs) > 2 and op.inputs[2] >= 0:
            inputs.append(self.out.constant(self.const(op, op.inputs[2], "the bias").astype(np.float32),
                                            f"b{op.index}"))
        y = self.out.node("Conv", inputs, f"conv{op.index}", kernel_shape=list(kernel), strides=list(strides),
                          dilations=list(dilations), pads=pads, group=group)
        self.emit(op, self.activation(op, y, opts.FusedActivationFunction()), NCHW)

    def op_CONV_2D(self, op: Operator) -> None:
        w = self.const(op, op.inputs[1], "the filter")  # OHWI
        if w.ndim != 4 or w.shape[3] != self.tensor(op.inputs[0]).shape[3]:
            raise self.fail(op, f"filter shape {w.shape} does not match the input")
        self._conv(op, w.transpose(0, 3, 1, 2), 1, op.options)

    def op_DEPTHWISE_CONV_2D(self, op: Operator) -> None:
        w = self.const(op, op.inputs[1], "the filter")  # [1, H, W, C*M]
        channels = self.tensor(op.inputs[0]).shape[3]
        if w.ndim != 4 or w.shape[0] != 1 or w.shape[3] % channels:
            raise self.fail(op, f"depthwise filter shape {w.shape} does not fit {channels} input channels")
        self._conv(op, w.transpose(3, 0, 1, 2), channels, op.options)  # -> [C*M, 1, H, W], group C

    def op_MAX_POOL_2D(self, op: Operator) -> None:
        o = op.options
        x_t = self.tensor(op.inputs[0])
        x = self.input(op, op.inputs[0], NCHW)
        kernel, strides = (o.FilterHeight(), o.FilterWidth()), (o.StrideH(), o.StrideW())
        pads = self.same_pads(op, x_t.shape[1:3], kernel, strides, (1, 1), o.Padding())
        y = self.out.node("MaxPool", [x], f"maxpool{op.index}", kernel_shape=list(kernel),
                          strides=list(strides), pads=pads)
        self.emit(op, self.activation(op, y, o.FusedActivationFunction()), NCHW)

    def op_ADD(self, op: Operator) -> None:
        layout = NCHW if self.rank(op.outputs[0]) == 4 else NHWC
        a, b = (self.input(op, i, layout) for i in op.inputs[:2])
        y = self.out.node("Add", [a, b], f"add{op.index}")
        fused = op.options.FusedActivationFunction() if op.options is not None else 0
        self.emit(op, self.activation(op, y, fused), layout)

    def op_PAD(self, op: Operator) -> None:
        paddings = self.const(op, op.inputs[1], "the paddings").astype(np.int64).reshape(-1, 2)
        rank = self.rank(op.inputs[0])
        if paddings.shape[0] != rank:
            raise self.fail(op, f"paddings for rank {paddings.shape[0]}, input rank {rank}")
        layout = NCHW if rank == 4 else NHWC
        if layout == NCHW:
            paddings = paddings[list(TO_NCHW)]
        x = self.input(op, op.inputs[0], layout)
        pads = self.out.constant(np.concatenate([paddings[:, 0], paddings[:, 1]]), f"pads{op.index}")
        self.emit(op, self.out.node("Pad", [x, pads], f"pad{op.index}", mode="constant"), layout)

    def op_RESIZE_BILINEAR(self, op: Operator) -> None:
        o = op.options
        align, half = (o.AlignCorners(), o.HalfPixelCenters()) if o is not None else (False, False)
        if align and half:
            raise self.fail(op, "align_corners and half_pixel_centers both set")
        mode = "align_corners" if align else "half_pixel" if half else "asymmetric"
        size = self.const(op, op.inputs[1], "the output size").astype(np.int64).reshape(-1)
        x_t = self.tensor(op.inputs[0])
        sizes = np.array([x_t.shape[0], x_t.shape[3], size[0], size[1]], np.int64)
        x = self.input(op, op.inputs[0], NCHW)
        y = self.out.node("Resize", [x, "", "", self.out.constant(sizes, f"sizes{op.index}")],
                          f"resize{op.index}", mode="linear", coordinate_transformation_mode=mode)
        self.emit(op, y, NCHW)

    def op_RESHAPE(self, op: Operator) -> None:
        if len(op.inputs) > 1 and op.inputs[1] >= 0:
            shape = self.const(op, op.inputs[1], "the new shape").astype(np.int64).reshape(-1)
        elif op.options is not None and op.options.NewShapeLength():
            shape = op.options.NewShapeAsNumpy().astype(np.int64)
        else:
            shape = np.array(self.tensor(op.outputs[0]).shape, np.int64)
        x = self.input(op, op.inputs[0], NHWC)  # element order is TFLite's
        y = self.out.node("Reshape", [x, self.out.constant(shape, f"shape{op.index}")], f"reshape{op.index}")
        self.emit(op, y, NHWC)

    def op_CONCATENATION(self, op: Operator) -> None:
        rank = self.rank(op.outputs[0])
        axis = op.options.Axis() % rank
        layout = NCHW if rank == 4 else NHWC
        if layout == NCHW:
            axis = NHWC_AXIS_TO_NCHW[axis]
        xs = [self.input(op, i, layout) for i in op.inputs]
        y = self.out.node("Concat", xs, f"concat{op.index}", axis=axis)
        self.emit(op, self.activation(op, y, op.options.FusedActivationFunction()), layout)

    def op_DEPTH_TO_SPACE(self, op: Operator) -> None:
        x = self.input(op, op.inputs[0], NCHW)
        # TFLite's channel order is (block_row, block_col, channel) = ONNX mode DCR.
        y = self.out.node("DepthToSpace", [x], f"d2s{op.index}", blocksize=op.options.BlockSize(), mode="DCR")
        self.emit(op, y, NCHW)

    def op_LOGISTIC(self, op: Operator) -> None:
        if op.inputs[0] in self.consts:
            raise self.fail(op, "constant input")
        x, layout = self.out.any_value(op.inputs[0])
        self.emit(op, self.out.node("Sigmoid", [x], f"sigmoid{op.index}"), layout)

    # ---- whole graph -------------------------------------------------------------------------------
    def run(self) -> onnx.ModelProto:
        handlers: dict[str, Callable[[Operator], None]] = {
            name: getattr(self, f"op_{name}") for name in SUPPORTED_OPS
        }
        unknown = sorted({op.name for op in self.operators if op.name not in handlers})
        if unknown:
            raise UnsupportedOperatorError(
                f"{self.model_name}: unsupported TFLite operator(s) {', '.join(unknown)} "
                f"(the posed converter supports {', '.join(SUPPORTED_OPS)})")
        inputs = []
        for i in self.g.inputs:
            t = self.tensor(i)
            if t.dtype != np.float32:
                raise ConversionError(f"{self.model_name}: input {t.name!r} is {t.type_name}, "
                                      "expected FLOAT32")
            inputs.append(value_info(t.name, t.shape))
            self.out._names.add(t.name)
            self.out.bind(i, t.name, NHWC)
        output_names = {self.tensor(i).name for i in self.outputs}
        self.out._names.update(output_names)
        for op in self.operators:
            handlers[op.name](op)
        outputs = []
        for i in self.outputs:
            t = self.tensor(i)
            if not self.out.has(i):
                raise ConversionError(f"{self.model_name}: output {t.name!r} is not computed by the graph")
            src = self.out.value(i, NHWC)
            self.out.nodes.append(helper.make_node("Identity", [src], [t.name], name=f"output_{t.name}"))
            outputs.append(value_info(t.name, t.shape))
        graph = helper.make_graph(self.out.nodes, self.model_name, inputs, outputs, self.out.initializers)
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                                  producer_name="posed-convert", producer_version=CONVERTER_VERSION)
        model.ir_version = IR_VERSION
        self.check_shapes(model)
        return model

    def check_shapes(self, model: onnx.ModelProto) -> None:
        """Every converted tensor must have the TFLite shape (permuted when held NCHW)."""
        try:
            onnx.checker.check_model(model)
            inferred = onnx.shape_inference.infer_shapes(model, strict_mode=True)
        except Exception as exc:
            raise ConversionError(f"{self.model_name}: the converted graph is invalid: {exc}") from exc
        shapes = {v.name: tuple(d.dim_value for d in v.type.tensor_type.shape.dim)
                  for v in [*inferred.graph.value_info, *inferred.graph.output, *inferred.graph.input]}
        for index, held in self.out._values.items():
            expected = self.tensor(index).shape
            for layout, name in held.items():
                want = tuple(expected[p] for p in TO_NCHW) if layout == NCHW else expected
                got = shapes.get(name)
                if got is not None and got != want:
                    tname = self.tensor(index).name
                    raise ConversionError(f"{self.model_name}: tensor {tname!r} converts to shape {got}, "
                                          f"expected {want} ({layout})")


SUPPORTED_OPS = (
    "CONV_2D", "DEPTHWISE_CONV_2D", "ADD", "PAD", "MAX_POOL_2D", "RESIZE_BILINEAR", "RESHAPE",
    "CONCATENATION", "DEPTH_TO_SPACE", "LOGISTIC", "DEQUANTIZE", "DENSIFY",
)


def convert(tflite_bytes: bytes, model_name: str = "model",
            outputs: Collection[str] | None = None) -> onnx.ModelProto:
    """Convert the bytes of a ``.tflite`` file to an ONNX model (opset 17, float32).

    ``outputs``: names of the TFLite outputs to keep (None = all); the operators only the others need are
    dropped. Raises ``UnsupportedOperatorError`` naming the operator(s) and the model, ``ConversionError`` for
    anything else the converter cannot express, ``TFLiteFormatError`` for a corrupt file.
    """
    return _Converter(read_graph(tflite_bytes), model_name, outputs).run()
