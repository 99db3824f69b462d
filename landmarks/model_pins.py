"""What this posed runs: the MediaPipe release its landmark models come from, their pinned sha256, and the
converter version whose ONNX files it was validated with. Standard library only: the daemon checks a models
folder's manifest against these at every start (``landmarks.models.verify_models``), and ``posed models
fetch`` (``landmarks.convert.fetch``) obtains and checks exactly these files.

A new mediapipe release changes nothing here: the wheel is asked for by its exact version, and the two
TFLite files inside it must have these hashes whatever the wheel (any platform's holds the same files).
"""

from __future__ import annotations

from dataclasses import dataclass

MEDIAPIPE_VERSION = "0.10.21"
# Any platform's wheel holds the same two files; this one is asked for explicitly so the download works
# from any host (e.g. another Python version or an ARM board).
WHEEL_PLATFORM = ("manylinux_2_28_x86_64", "3.11", "cp", "cp311")
WHEEL_NAME = f"mediapipe-{MEDIAPIPE_VERSION}-cp311-cp311-manylinux_2_28_x86_64.whl"
WHEEL_SHA256 = "05dc4a9e593655a79558d05d6227d31018c2537a4bd3362b51e230cf22aecfe3"  # recorded, not required

# The converter version whose ONNX files this posed runs (``landmarks.convert.converter`` takes it from here),
# kept in this standard-library module so that the daemon, which has no converter installed, can tell a folder
# converted by another version.
CONVERTER_VERSION = "2"

DETECTOR_TFLITE = "pose_detection.tflite"
LANDMARK_TFLITE = "pose_landmark_full.tflite"
DETECTOR_ONNX = "pose_detection.onnx"
LANDMARK_ONNX = "pose_landmark_full.onnx"


@dataclass(frozen=True)
class PinnedModel:
    name: str  # file name in the models folder
    member: str  # path inside the mediapipe wheel
    sha256: str
    size: int
    onnx_name: str
    outputs: tuple[str, ...] | None = None  # TFLite outputs the ONNX model keeps (None = all)


# The landmark model's outputs: Identity = 39 landmarks in crop pixels, Identity_1 = pose flag,
# Identity_2 = 256x256 segmentation logits, Identity_3 = 64x64x39 heatmap, Identity_4 = 39 world landmarks.
# posed never reads the segmentation mask, and computing it is about 45% of the model's time, so the
# converted model leaves it out.
LANDMARK_OUTPUTS = ("Identity", "Identity_1", "Identity_3", "Identity_4")

PINNED = (
    PinnedModel(DETECTOR_TFLITE, "mediapipe/modules/pose_detection/pose_detection.tflite",
                "9ba9dd3d42efaaba86b4ff0122b06f29c4122e756b329d89dca1e297fd8f866c", 2_959_046, DETECTOR_ONNX),
    PinnedModel(LANDMARK_TFLITE, "mediapipe/modules/pose_landmark/pose_landmark_full.tflite",
                "e9a5c5cb17f736fafd4c2ec1da3b3d331d6edbe8a0d32395855aeb2cdfd64b9f", 6_440_512, LANDMARK_ONNX,
                LANDMARK_OUTPUTS),
)
