"""How far the converted ONNX models are from the original TFLite models, output by output.

Three float32 results of the same model on the same input tensor — onnxruntime on the ONNX file, LiteRT's
built-in kernels and LiteRT's XNNPACK delegate (MediaPipe's own runtime) on the ``.tflite`` file — and, on
request, the exact result: the converted graph evaluated in float64 by onnx's reference evaluator. Used by
``posed bench convert`` and the equivalence tests. LiteRT (``ai-edge-litert``) is a test extra; it is
imported only when called.

Real inputs are built as the pipeline builds them (:mod:`landmarks.crop`): the detector sees the whole frame
letterboxed to 224×224 (zero border) in [-1, 1]; the landmark model the centred square of the frame at
256×256 in [0, 1]; RGB, NHWC float32, batch 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnx
from onnx import numpy_helper

from posed.landmarks import DETECTOR_INPUT_SIZE, LANDMARK_INPUT_SIZE, Roi, detector_input, landmark_input

MODEL_INPUTS = {"pose_detection": (DETECTOR_INPUT_SIZE, -1.0),  # side, lowest
                "pose_landmark_full": (LANDMARK_INPUT_SIZE, 0.0)}


def model_input(bgr: np.ndarray, model: str) -> np.ndarray:
    """A BGR image as ``model`` ("pose_detection" or "pose_landmark_full") is fed: the detector gets the whole
    frame letterboxed, the landmark model the centred square; (1, side, side, 3) float32."""
    if model == "pose_detection":
        return detector_input(bgr)[0]
    if model == "pose_landmark_full":
        h, w = bgr.shape[:2]
        return landmark_input(bgr, Roi(w / 2, h / 2, min(w, h), 0.0))
    raise ValueError(f"unknown model {model!r}; choose one of {', '.join(MODEL_INPUTS)}")


def random_input(model: str, seed: int) -> np.ndarray:
    """Uniform noise over the model's input range, (1, side, side, 3) float32, from ``seed``."""
    side, lo = MODEL_INPUTS[model]
    return np.random.default_rng(seed).uniform(lo, 1.0, (1, side, side, 3)).astype(np.float32)


def litert_outputs(tflite_path: Path, x: np.ndarray, kernels: str) -> dict[str, np.ndarray]:
    """Every output of the ``.tflite`` model on ``x`` by LiteRT, 1 thread; ``kernels`` "built-in" or
    "XNNPACK"."""
    from ai_edge_litert.interpreter import Interpreter, OpResolverType

    resolvers = {"built-in": OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES, "XNNPACK": OpResolverType.AUTO}
    if kernels not in resolvers:
        raise ValueError(f"unknown LiteRT kernels {kernels!r}; choose one of {', '.join(resolvers)}")
    it = Interpreter(model_path=str(tflite_path), experimental_op_resolver_type=resolvers[kernels], num_threads=1)
    it.allocate_tensors()
    it.set_tensor(it.get_input_details()[0]["index"], x)
    it.invoke()
    return {d["name"]: it.get_tensor(d["index"]).copy() for d in it.get_output_details()}


def float64_model(model: onnx.ModelProto) -> onnx.ModelProto:
    """A copy of ``model`` with every float32 initializer, input, output and value made float64."""
    m = onnx.ModelProto()
    m.CopyFrom(model)
    for init in m.graph.initializer:
        if init.data_type == onnx.TensorProto.FLOAT:
            init.CopyFrom(numpy_helper.from_array(numpy_helper.to_array(init).astype(np.float64), init.name))
    for v in [*m.graph.input, *m.graph.output, *m.graph.value_info]:
        if v.type.tensor_type.elem_type == onnx.TensorProto.FLOAT:
            v.type.tensor_type.elem_type = onnx.TensorProto.DOUBLE
    return m


class ExactModel:
    """The converted graph evaluated in float64 (onnx.reference; ~1 s per call on these models)."""

    def __init__(self, model: onnx.ModelProto) -> None:
        from onnx.reference import ReferenceEvaluator

        self.input = model.graph.input[0].name
        self.outputs = [o.name for o in model.graph.output]
        self._evaluator = ReferenceEvaluator(float64_model(model))

    def __call__(self, x: np.ndarray) -> dict[str, np.ndarray]:
        values = self._evaluator.run(self.outputs, {self.input: x.astype(np.float64)})
        return dict(zip(self.outputs, values, strict=True))


# The equivalence criterion (docs/models.md, "Equivalence"): the reference is the exact result, the converted
# graph evaluated in float64. For every kept output on every input, onnxruntime's max error against it must be
#  (1) within EXACT_ABS + EXACT_REL * max|exact value of that output|: 1e-3 absolute plus a float32-scale
#      relative term (2e-5 is ~170 ulps of float32's 2^-23 relative step, room for rounding accumulated over
#      ~100 layers; a converter bug is 10^4-10^6 times larger), and
#  (2) no worse than LITERT_FACTOR x the worse of LiteRT's two kernel sets (MediaPipe's own runtime) against the
#      same exact result. Below UNIT_ROUNDING (4 float32 ulps at 1.0) errors cannot be ranked: a probability
#      output that one kernel rounds to the nearest float32 and another does not differ by 6e-8, and a logit of
#      -20 whose sigmoid is 2e-9 in float64 may come out 0; there (2) is met by definition.
# Nothing in it is measured on one machine: the float64 result is the same on every CPU, and LiteRT's errors
# are measured on the machine that runs the check.
EXACT_ABS = 1e-3
EXACT_REL = 2e-5
LITERT_FACTOR = 1.5
UNIT_ROUNDING = 4 * 2.0**-23


@dataclass(frozen=True)
class OutputDiff:
    """Max absolute differences on one output for one input (units of the output)."""

    output: str
    onnx_vs_builtin: float
    onnx_vs_xnnpack: float
    litert_spread: float  # LiteRT built-in vs XNNPACK: float32's own reproducibility on this output
    max_abs_value: float
    exact_error: dict[str, float] | None = None  # "onnx", "built-in", "XNNPACK" vs the float64 result
    max_abs_exact: float | None = None  # largest |value| of the float64 result on this output

    @property
    def worst(self) -> float:
        return max(self.onnx_vs_builtin, self.onnx_vs_xnnpack)

    @property
    def exact_bound(self) -> float:
        """Criterion (1): the largest error against the exact result that onnxruntime may have."""
        if self.max_abs_exact is None:
            raise ValueError(f"output {self.output}: no exact result was computed (pass exact= to diff_outputs)")
        return EXACT_ABS + EXACT_REL * self.max_abs_exact

    @property
    def litert_bound(self) -> float:
        """Criterion (2): LITERT_FACTOR x the worse LiteRT kernel set's error, at least UNIT_ROUNDING."""
        if self.exact_error is None:
            raise ValueError(f"output {self.output}: no exact result was computed (pass exact= to diff_outputs)")
        return max(UNIT_ROUNDING, LITERT_FACTOR * max(self.exact_error["built-in"], self.exact_error["XNNPACK"]))

    @property
    def equivalent(self) -> bool:
        """Both criteria met: onnxruntime is as close to the exact result as the criterion asks."""
        return self.exact_error["onnx"] <= self.exact_bound and self.exact_error["onnx"] <= self.litert_bound


def diff_outputs(onnx_out: dict[str, np.ndarray], builtin: dict[str, np.ndarray], xnnpack: dict[str, np.ndarray],
                 exact: dict[str, np.ndarray] | None = None) -> list[OutputDiff]:
    """One :class:`OutputDiff` per onnxruntime output (the ONNX model may keep fewer outputs than LiteRT's)."""
    rows = []
    for name, value in onnx_out.items():
        ref, other = builtin[name], xnnpack[name]
        if value.shape != ref.shape:
            raise ValueError(f"output {name}: onnx shape {value.shape} != TFLite shape {ref.shape}")
        errors = max_abs_exact = None
        if exact is not None:
            errors = {label: float(np.abs(v.astype(np.float64) - exact[name]).max())
                      for label, v in (("onnx", value), ("built-in", ref), ("XNNPACK", other))}
            max_abs_exact = float(np.abs(exact[name]).max())
        rows.append(OutputDiff(name, float(np.abs(value - ref).max()), float(np.abs(value - other).max()),
                               float(np.abs(ref - other).max()), float(np.abs(ref).max()), errors, max_abs_exact))
    return rows
