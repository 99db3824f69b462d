"""An ONNX graph under construction that remembers, for every TFLite tensor, the ONNX value holding it
and that value's layout.

TFLite activations are NHWC; ONNX convolutions are NCHW. Rank-4 activations are kept in NCHW between
convolutions and transposed only where an operator depends on the element order (RESHAPE, graph outputs):
``value(t, NHWC)`` / ``value(t, NCHW)`` insert (once) the Transpose needed.
"""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

NHWC = "NHWC"  # TFLite's own order (also used for tensors of rank != 4)
NCHW = "NCHW"
TO_NCHW = (0, 3, 1, 2)
TO_NHWC = (0, 2, 3, 1)


class OnnxGraph:
    def __init__(self) -> None:
        self.nodes: list[onnx.NodeProto] = []
        self.initializers: list[onnx.TensorProto] = []
        self._values: dict[int, dict[str, str]] = {}  # tflite tensor index -> {layout: onnx name}
        self._names: set[str] = set()

    def fresh(self, base: str) -> str:
        """A value name not used yet."""
        name, n = base, 1
        while name in self._names:
            name, n = f"{base}_{n}", n + 1
        self._names.add(name)
        return name

    def constant(self, array: np.ndarray, base: str) -> str:
        """An initializer holding ``array``; returns its name."""
        name = self.fresh(base)
        self.initializers.append(numpy_helper.from_array(np.ascontiguousarray(array), name))
        return name

    def node(self, op_type: str, inputs: list[str], base: str, **attrs) -> str:
        """Append one single-output node; returns the output name."""
        out = self.fresh(base)
        self.nodes.append(helper.make_node(op_type, inputs, [out], name=out, **attrs))
        return out

    def bind(self, tensor: int, name: str, layout: str) -> None:
        """Record that ONNX value ``name`` holds TFLite tensor ``tensor`` in ``layout``."""
        self._values.setdefault(tensor, {})[layout] = name

    def has(self, tensor: int) -> bool:
        return tensor in self._values

    def value(self, tensor: int, layout: str) -> str:
        """The ONNX value of ``tensor`` in ``layout``, transposing (once) when needed."""
        held = self._values[tensor]
        if layout in held:
            return held[layout]
        src_layout, src = next(iter(held.items()))
        perm = TO_NCHW if layout == NCHW else TO_NHWC
        name = self.node("Transpose", [src], f"{src}_to_{layout.lower()}", perm=list(perm))
        assert src_layout != layout
        held[layout] = name
        return name

    def any_value(self, tensor: int) -> tuple[str, str]:
        """Some ONNX value of ``tensor`` and its layout (for layout-agnostic element-wise ops)."""
        held = self._values[tensor]
        if NCHW in held:
            return held[NCHW], NCHW
        layout, name = next(iter(held.items()))
        return name, layout


def value_info(name: str, shape: tuple[int, ...]) -> onnx.ValueInfoProto:
    return helper.make_tensor_value_info(name, TensorProto.FLOAT, list(shape))
