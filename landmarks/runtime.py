"""onnxruntime sessions for the two BlazePose models, with their outputs in a fixed order.

A model is wrapped in a small callable: ``detector(tensor) -> DetectorOutputs`` and
``landmark_model(tensor) -> LandmarkOutputs``, tensors NHWC float32 as :mod:`landmarks.crop` builds them. The
outputs are recognised by shape, not by name, so a converter may name them as it likes; an NCHW input or
heatmap is accepted and transposed. Anything else is refused at load time with a message naming the file,
what was expected and what was found.

Session options (measured in docs/bench/landmarks.md): graph optimization level ALL, ``threads`` intra-op
threads, one inter-op thread, sequential execution, spinning of idle intra-op threads off (the daemon's other
processes share the cores). The segmentation output is never requested.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Protocol

import numpy as np
import onnxruntime as ort

from posed.landmarks.anchors import INPUT_SIZE as DETECTOR_INPUT
from posed.landmarks.anchors import NUM_ANCHORS
from posed.landmarks.decode import CROP_SIZE as LANDMARK_INPUT
from posed.landmarks.models import ModelCorruptError, ModelMissingError


class ModelLoadError(ModelCorruptError):
    """A model file exists but onnxruntime cannot use it (corrupt, truncated, or not the expected model)."""


class DetectorOutputs(NamedTuple):
    boxes: np.ndarray   # (2254, 12) regressors
    scores: np.ndarray  # (2254,) logits


class LandmarkOutputs(NamedTuple):
    landmarks: np.ndarray  # (195,) 39 × (x, y, z, visibility logit, presence logit), crop pixels
    pose_flag: float       # probability that a pose is in the crop
    heatmap: np.ndarray    # (64, 64, 39) logits, HWC
    world: np.ndarray      # (117,) 39 × (x, y, z) metres


class DetectorRunner(Protocol):
    def __call__(self, tensor: np.ndarray) -> DetectorOutputs: ...


class LandmarkRunner(Protocol):
    def __call__(self, tensor: np.ndarray) -> LandmarkOutputs: ...


@dataclass(frozen=True)
class SessionSettings:
    """How onnxruntime runs a model."""

    threads: int = 1
    optimization: str = "all"  # "disable", "basic", "extended", "all"
    spinning: bool = False

    def session_options(self) -> ort.SessionOptions:
        opts = ort.SessionOptions()
        opts.graph_optimization_level = {
            "disable": ort.GraphOptimizationLevel.ORT_DISABLE_ALL,
            "basic": ort.GraphOptimizationLevel.ORT_ENABLE_BASIC,
            "extended": ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED,
            "all": ort.GraphOptimizationLevel.ORT_ENABLE_ALL,
        }[self.optimization]
        opts.intra_op_num_threads = self.threads
        opts.inter_op_num_threads = 1
        opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        opts.add_session_config_entry("session.intra_op.allow_spinning", "1" if self.spinning else "0")
        opts.log_severity_level = 3
        return opts


def open_session(path: Path, settings: SessionSettings, model: bytes | None = None) -> ort.InferenceSession:
    """An onnxruntime CPU session for ``path`` (or for the serialized ``model``, ``path`` then only names it in
    messages); a model that cannot be loaded raises :class:`ModelLoadError`."""
    path = Path(path)
    if model is None and not path.is_file():
        raise ModelMissingError(f"landmark model {path} is missing; run `posed models fetch`")
    try:
        return ort.InferenceSession(os.fspath(path) if model is None else model,
                                    sess_options=settings.session_options(), providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own pybind exception types
        raise ModelLoadError(
            f"{path}: onnxruntime cannot load this model ({type(exc).__name__}: {str(exc).strip()[:300]}); "
            "the file is corrupt or not a converted BlazePose model: delete it and run `posed models fetch`"
        ) from exc


def _dims(shape: list) -> tuple:
    return tuple(d if isinstance(d, int) else -1 for d in shape)


def _input_layout(session: ort.InferenceSession, path: Path, size: int) -> tuple[str, bool]:
    """Name of the single image input and whether it is NCHW."""
    inputs = session.get_inputs()
    if len(inputs) != 1:
        raise ModelLoadError(f"{path}: expected one input, found {len(inputs)}: {[i.name for i in inputs]}")
    dims = _dims(inputs[0].shape)
    if len(dims) == 4 and dims[1:] == (size, size, 3):
        return inputs[0].name, False
    if len(dims) == 4 and dims[1:] == (3, size, size):
        return inputs[0].name, True
    raise ModelLoadError(f"{path}: input {inputs[0].name!r} has shape {list(inputs[0].shape)}, expected "
                         f"[1, {size}, {size}, 3] (NHWC) or [1, 3, {size}, {size}]")


def _find_output(session: ort.InferenceSession, path: Path, what: str, *shapes: tuple) -> tuple[str, tuple]:
    for out in session.get_outputs():
        dims = _dims(out.shape)
        for shape in shapes:
            if len(dims) == len(shape) and all(d == s or d == -1 for d, s in zip(dims, shape, strict=True)) \
                    and dims[1:] == shape[1:]:
                return out.name, shape
    found = ", ".join(f"{o.name} {list(o.shape)}" for o in session.get_outputs())
    expected = " or ".join(str(list(s)) for s in shapes)
    raise ModelLoadError(f"{path}: no output for the {what} with shape {expected}; outputs are: {found}")


class OnnxDetector:
    """The pose detector on onnxruntime: (1, 224, 224, 3) float32 [−1, 1] RGB → raw boxes and score logits."""

    def __init__(self, path: Path, settings: SessionSettings = SessionSettings(),
                 model: bytes | None = None) -> None:
        self.path = Path(path)
        self.session = open_session(self.path, settings, model)
        self.input_name, self.nchw = _input_layout(self.session, self.path, DETECTOR_INPUT)
        self.boxes_name, _ = _find_output(self.session, self.path, "boxes", (1, NUM_ANCHORS, 12))
        self.scores_name, _ = _find_output(self.session, self.path, "scores", (1, NUM_ANCHORS, 1),
                                           (1, NUM_ANCHORS))
        self._outputs = [self.boxes_name, self.scores_name]

    def __call__(self, tensor: np.ndarray) -> DetectorOutputs:
        x = np.ascontiguousarray(tensor.transpose(0, 3, 1, 2)) if self.nchw else tensor
        boxes, scores = self.session.run(self._outputs, {self.input_name: x})
        return DetectorOutputs(boxes.reshape(NUM_ANCHORS, 12), scores.reshape(NUM_ANCHORS))


class OnnxLandmarkModel:
    """The pose landmark model (full) on onnxruntime: (1, 256, 256, 3) float32 [0, 1] RGB crop → tensors."""

    def __init__(self, path: Path, settings: SessionSettings = SessionSettings(),
                 model: bytes | None = None) -> None:
        self.path = Path(path)
        self.session = open_session(self.path, settings, model)
        self.input_name, self.nchw = _input_layout(self.session, self.path, LANDMARK_INPUT)
        self.landmarks_name, _ = _find_output(self.session, self.path, "landmarks", (1, 195))
        self.flag_name, _ = _find_output(self.session, self.path, "pose flag", (1, 1))
        self.heatmap_name, hm_shape = _find_output(self.session, self.path, "heatmap", (1, 64, 64, 39),
                                                   (1, 39, 64, 64))
        self.heatmap_nchw = hm_shape == (1, 39, 64, 64)
        self.world_name, _ = _find_output(self.session, self.path, "world landmarks", (1, 117))
        self._outputs = [self.landmarks_name, self.flag_name, self.heatmap_name, self.world_name]

    def __call__(self, tensor: np.ndarray) -> LandmarkOutputs:
        x = np.ascontiguousarray(tensor.transpose(0, 3, 1, 2)) if self.nchw else tensor
        lms, flag, heatmap, world = self.session.run(self._outputs, {self.input_name: x})
        heatmap = heatmap[0].transpose(1, 2, 0) if self.heatmap_nchw else heatmap[0]
        return LandmarkOutputs(lms.reshape(195), float(flag.reshape(-1)[0]), heatmap, world.reshape(117))
