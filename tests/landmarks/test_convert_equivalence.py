"""The converted pose models (the ONNX files in the models folder, run by onnxruntime) against the original
TFLite files run by LiteRT, on a real image and on random input.

Float32 rounding differs between any two kernel libraries; LiteRT's own XNNPACK and built-in kernels disagree
by up to ~1 on the segmentation logits (|values| up to ~1700) and up to ~6e-3 px on the landmarks. So:
* on the real image every output is within 1e-3 absolute of LiteRT (segmentation: after the sigmoid);
* on every input every output is within max(1e-3, 3 x the XNNPACK-vs-built-in spread of LiteRT itself)
  (converter bugs show up 10^4-10^6 times larger: a wrong resize mode or SAME-pad side gives 50-1700).
"""

from __future__ import annotations

import hashlib

import cv2
import numpy as np
import onnx
import onnxruntime as ort
import pytest
from ai_edge_litert.interpreter import Interpreter, OpResolverType

from landmarks.convert import convert
from landmarks.convert.tflite_graph import read_graph

MODELS = {"detector": ("pose_detection", 224, "signed"), "landmark": ("pose_landmark_full", 256, "unit")}
SEGMENTATION = "Identity_2"  # landmark model: segmentation logits


def sigmoid(v: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * v.astype(np.float64)))


def real_input(shared_data, size: int, value_range: str) -> np.ndarray:
    """pose.jpg as MediaPipe feeds it: detector = whole frame letterboxed (zero border), [-1, 1];
    landmark = square crop around the person, [0, 1]; RGB, NHWC."""
    bgr = cv2.imread(str(shared_data / "reference" / "mediapipe_pose_jpg" / "pose.jpg"))
    assert bgr is not None, "pose.jpg missing from the shared data"
    rgb = np.ascontiguousarray(bgr[:, :, ::-1])
    h, w = rgb.shape[:2]
    if value_range == "signed":
        scale = size / max(h, w)
        resized = cv2.resize(rgb, (round(w * scale), round(h * scale)), interpolation=cv2.INTER_LINEAR)
        canvas = np.zeros((size, size, 3), np.uint8)
        top, left = (size - resized.shape[0]) // 2, (size - resized.shape[1]) // 2
        canvas[top:top + resized.shape[0], left:left + resized.shape[1]] = resized
        x = canvas.astype(np.float32) / 127.5 - 1.0
    else:
        side = min(h, w)
        crop = rgb[(h - side) // 2:(h + side) // 2, (w - side) // 2:(w + side) // 2]
        x = cv2.resize(crop, (size, size), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    return x[None]


def random_input(size: int, value_range: str, seed: int) -> np.ndarray:
    lo = -1.0 if value_range == "signed" else 0.0
    return np.random.default_rng(seed).uniform(lo, 1.0, (1, size, size, 3)).astype(np.float32)


def litert(path, x, resolver) -> dict[str, np.ndarray]:
    it = Interpreter(model_path=str(path), experimental_op_resolver_type=resolver, num_threads=1)
    it.allocate_tensors()
    it.set_tensor(it.get_input_details()[0]["index"], x)
    it.invoke()
    return {d["name"]: it.get_tensor(d["index"]).copy() for d in it.get_output_details()}


@pytest.fixture(scope="module")
def sessions(models_dir):
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    return {key: ort.InferenceSession(str(models_dir / f"{name}.onnx"), opts, providers=["CPUExecutionProvider"])
            for key, (name, _, _) in MODELS.items()}


def compare(models_dir, sessions, key, x):
    name = MODELS[key][0]
    tfl = models_dir / f"{name}.tflite"
    builtin = litert(tfl, x, OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
    xnnpack = litert(tfl, x, OpResolverType.AUTO)
    sess = sessions[key]
    got = dict(zip([o.name for o in sess.get_outputs()], sess.run(None, {"input_1": x}), strict=True))
    assert set(got) == set(builtin)
    return builtin, xnnpack, got


@pytest.mark.parametrize("key", MODELS)
def test_real_image_every_output_within_1e3(models_dir, sessions, shared_data, key):
    _, size, value_range = MODELS[key]
    builtin, xnnpack, got = compare(models_dir, sessions, key, real_input(shared_data, size, value_range))
    report = {}
    for out, ref in builtin.items():
        assert got[out].shape == ref.shape, out
        if out == SEGMENTATION and key == "landmark":
            diff = np.abs(sigmoid(got[out]) - sigmoid(ref)).max()
        else:
            diff = np.abs(got[out] - ref).max()
        report[out] = diff
        assert diff <= 1e-3, f"{key} {out}: max |onnx - litert| = {diff:.3g}"
    print(key, {k: f"{v:.2g}" for k, v in report.items()})


@pytest.mark.parametrize("key", MODELS)
@pytest.mark.parametrize("source", ["real", "random0", "random1"])
def test_within_litert_own_kernel_spread(models_dir, sessions, shared_data, key, source):
    _, size, value_range = MODELS[key]
    x = (real_input(shared_data, size, value_range) if source == "real"
         else random_input(size, value_range, int(source[-1])))
    builtin, xnnpack, got = compare(models_dir, sessions, key, x)
    for out, ref in builtin.items():
        spread = np.abs(xnnpack[out] - ref).max()
        tol = max(1e-3, 3.0 * spread)
        for other, label in ((ref, "built-in"), (xnnpack[out], "XNNPACK")):
            diff = np.abs(got[out] - other).max()
            assert diff <= tol, (f"{key} {out} on {source}: |onnx - litert {label}| = {diff:.3g} > {tol:.3g} "
                                 f"(litert's own spread {spread:.3g})")


@pytest.mark.parametrize("key", MODELS)
def test_interface_is_the_tflite_one(models_dir, sessions, key):
    name = MODELS[key][0]
    graph = read_graph((models_dir / f"{name}.tflite").read_bytes())
    sess = sessions[key]
    want_in = [(graph.tensors[i].name, list(graph.tensors[i].shape)) for i in graph.inputs]
    want_out = [(graph.tensors[i].name, list(graph.tensors[i].shape)) for i in graph.outputs]
    assert [(i.name, i.shape) for i in sess.get_inputs()] == want_in
    assert [(o.name, o.shape) for o in sess.get_outputs()] == want_out
    assert all(i.type == "tensor(float)" for i in sess.get_inputs())


@pytest.mark.parametrize("key", MODELS)
def test_shipped_onnx_is_what_this_converter_makes(models_dir, key):
    """A fresh conversion is byte-identical to the file in the models folder (conversion is deterministic;
    a converter change without a CONVERTER_VERSION bump shows up here)."""
    name = MODELS[key][0]
    model = convert((models_dir / f"{name}.tflite").read_bytes(), name)
    fresh = model.SerializeToString()
    shipped = (models_dir / f"{name}.onnx").read_bytes()
    assert hashlib.sha256(fresh).hexdigest() == hashlib.sha256(shipped).hexdigest(), (
        f"{name}.onnx differs from a fresh conversion: bump CONVERTER_VERSION and run `posed models fetch`")
    onnx.checker.check_model(model)
    assert model.opset_import[0].version == 17
