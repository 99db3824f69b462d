"""2D body landmarks: MediaPipe Pose (BlazePose full) run by onnxruntime, and the landmark recording format.

Other packages import these names from ``landmarks`` itself, never from its modules:

* the landmarker: ``PoseLandmarker(config: LandmarkConfig, models_dir=None)`` with ``process(image_bgr, t,
  seq) -> LandmarkFrame``, ``process_full`` (everything found in the frame), ``reset()`` and ``warmup()``;
  ``LandmarkConfig`` is the config section ``landmarks``; ``rotate_image`` and ``rotate_points`` turn a
  frame and points by a multiple of 90 degrees as the pipeline does.
* the models folder: ``default_models_dir``, ``find_models``, ``verify_models``; a missing or damaged model
  raises ``ModelMissingError``, whose message names ``posed models fetch``.
* the two models alone (benchmarks): ``OnnxDetector``, ``OnnxLandmarkModel`` and their ``SessionSettings``
  and outputs ``DetectorOutputs``, ``LandmarkOutputs``; their inputs as the pipeline builds them,
  ``detector_input`` (the whole frame, ``DETECTOR_INPUT_SIZE`` square) and ``landmark_input`` (a ``Roi``,
  ``LANDMARK_INPUT_SIZE`` square).
* landmarks per frame and the ``*.landmarks.jsonl`` recording format: ``LandmarkFrame``, ``LANDMARK_NAMES``
  (the 33 in MediaPipe order), ``RecordingHeader``, ``iter_recording``, ``read_recording``,
  ``write_recording``, ``RecordingWriter``, ``RecordingError`` (an unreadable header), ``RecordingProblem``
  (a bad frame line) and ``dumps`` (one compact JSON line); ``iter_recording``'s stream is a ``FrameStream``
  whose ``invalid`` (``InvalidValues``) counts the visibility and presence values outside [0, 1] it read as
  unknown, reported at its end with an ``InvalidLandmarkValues`` warning; ``DepthSource`` (the header's ``depth``: where
  the frames' ``depth_m`` came from).
* depth at the landmarks (pure NumPy): ``sample_depth(depth, depth_scale, landmarks)`` (metres along the
  camera's z axis at each landmark's pixel of an aligned depth image, NaN where unknown), its default
  patch radius ``depth_patch_radius(width, height)``, and ``with_depth(frame, depth, depth_scale)`` (a
  ``LandmarkFrame`` with its ``depth_m`` filled in).
* left and right kept (pure NumPy): ``SideKeeper`` (one person's labels across frames, ``check``) and
  ``RecordingSides`` (a recording's frames, every person's labels put back where they flipped).

The model converter behind ``posed models fetch`` is the subpackage :mod:`landmarks.convert`, with its own
public names. The names here load on first use (PEP 562): ``import landmarks`` costs nothing; onnxruntime
loads only with the landmarker's names (``PoseLandmarker``, ``rotate_image``, ``rotate_points``) and the
models' (``OnnxDetector``, ``OnnxLandmarkModel``, ``SessionSettings``, their outputs), OpenCV also with
``detector_input`` and ``landmark_input``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from posed.landmarks.anchors import INPUT_SIZE as DETECTOR_INPUT_SIZE
    from posed.landmarks.config import LandmarkConfig
    from posed.landmarks.crop import detector_input, landmark_input
    from posed.landmarks.decode import CROP_SIZE as LANDMARK_INPUT_SIZE
    from posed.landmarks.depth import depth_patch_radius, sample_depth, with_depth
    from posed.landmarks.models import (
        ModelMissingError,
        ModelOutdatedError,
        check_provenance,
        default_models_dir,
        describe_models,
        find_models,
        installed_models,
        verify_models,
    )
    from posed.landmarks.people import MultiPoseLandmarker
    from posed.landmarks.pipeline import PoseLandmarker, rotate_image, rotate_points
    from posed.landmarks.recording import (
        LANDMARK_NAMES,
        DepthSource,
        FrameStream,
        InvalidLandmarkValues,
        InvalidValues,
        LandmarkFrame,
        PersonLandmarks,
        RecordingError,
        RecordingHeader,
        RecordingProblem,
        RecordingWriter,
        dumps,
        iter_recording,
        read_recording,
        write_recording,
    )
    from posed.landmarks.roi import Roi
    from posed.landmarks.runtime import (
        DetectorOutputs,
        LandmarkOutputs,
        OnnxDetector,
        OnnxLandmarkModel,
        SessionSettings,
    )
    from posed.landmarks.sides import RecordingSides, SideKeeper
    from posed.landmarks.tracks import PersonTracker, box_iou, landmark_box, oks

__all__ = [
    "DETECTOR_INPUT_SIZE",
    "LANDMARK_INPUT_SIZE",
    "LANDMARK_NAMES",
    "DepthSource",
    "DetectorOutputs",
    "LandmarkConfig",
    "LandmarkFrame",
    "LandmarkOutputs",
    "ModelMissingError",
    "ModelOutdatedError",
    "check_provenance",
    "describe_models",
    "installed_models",
    "OnnxDetector",
    "OnnxLandmarkModel",
    "MultiPoseLandmarker",
    "PersonLandmarks",
    "PersonTracker",
    "PoseLandmarker",
    "RecordingError",
    "RecordingHeader",
    "RecordingProblem",
    "RecordingWriter",
    "FrameStream",
    "InvalidLandmarkValues",
    "InvalidValues",
    "Roi",
    "SessionSettings",
    "default_models_dir",
    "depth_patch_radius",
    "detector_input",
    "dumps",
    "find_models",
    "oks",
    "iter_recording",
    "landmark_box",
    "box_iou",
    "landmark_input",
    "read_recording",
    "rotate_image",
    "rotate_points",
    "sample_depth",
    "SideKeeper",
    "RecordingSides",
    "verify_models",
    "with_depth",
    "write_recording",
]

# public name -> (module that defines it, its name there)
_ORIGIN = {
    "DETECTOR_INPUT_SIZE": ("posed.landmarks.anchors", "INPUT_SIZE"),
    "LandmarkConfig": ("posed.landmarks.config", "LandmarkConfig"),
    "detector_input": ("posed.landmarks.crop", "detector_input"),
    "landmark_input": ("posed.landmarks.crop", "landmark_input"),
    "LANDMARK_INPUT_SIZE": ("posed.landmarks.decode", "CROP_SIZE"),
    "depth_patch_radius": ("posed.landmarks.depth", "depth_patch_radius"),
    "sample_depth": ("posed.landmarks.depth", "sample_depth"),
    "with_depth": ("posed.landmarks.depth", "with_depth"),
    "SideKeeper": ("posed.landmarks.sides", "SideKeeper"),
    "RecordingSides": ("posed.landmarks.sides", "RecordingSides"),
    "ModelMissingError": ("posed.landmarks.models", "ModelMissingError"),
    "ModelOutdatedError": ("posed.landmarks.models", "ModelOutdatedError"),
    "check_provenance": ("posed.landmarks.models", "check_provenance"),
    "describe_models": ("posed.landmarks.models", "describe_models"),
    "installed_models": ("posed.landmarks.models", "installed_models"),
    "default_models_dir": ("posed.landmarks.models", "default_models_dir"),
    "find_models": ("posed.landmarks.models", "find_models"),
    "verify_models": ("posed.landmarks.models", "verify_models"),
    "PoseLandmarker": ("posed.landmarks.pipeline", "PoseLandmarker"),
    "MultiPoseLandmarker": ("posed.landmarks.people", "MultiPoseLandmarker"),
    "PersonTracker": ("posed.landmarks.tracks", "PersonTracker"),
    "landmark_box": ("posed.landmarks.tracks", "landmark_box"),
    "box_iou": ("posed.landmarks.tracks", "box_iou"),
    "oks": ("posed.landmarks.tracks", "oks"),
    "PersonLandmarks": ("posed.landmarks.recording", "PersonLandmarks"),
    "rotate_image": ("posed.landmarks.pipeline", "rotate_image"),
    "rotate_points": ("posed.landmarks.pipeline", "rotate_points"),
    "LANDMARK_NAMES": ("posed.landmarks.recording", "LANDMARK_NAMES"),
    "DepthSource": ("posed.landmarks.recording", "DepthSource"),
    "LandmarkFrame": ("posed.landmarks.recording", "LandmarkFrame"),
    "RecordingError": ("posed.landmarks.recording", "RecordingError"),
    "RecordingHeader": ("posed.landmarks.recording", "RecordingHeader"),
    "RecordingProblem": ("posed.landmarks.recording", "RecordingProblem"),
    "FrameStream": ("posed.landmarks.recording", "FrameStream"),
    "InvalidLandmarkValues": ("posed.landmarks.recording", "InvalidLandmarkValues"),
    "InvalidValues": ("posed.landmarks.recording", "InvalidValues"),
    "RecordingWriter": ("posed.landmarks.recording", "RecordingWriter"),
    "dumps": ("posed.landmarks.recording", "dumps"),
    "iter_recording": ("posed.landmarks.recording", "iter_recording"),
    "read_recording": ("posed.landmarks.recording", "read_recording"),
    "write_recording": ("posed.landmarks.recording", "write_recording"),
    "Roi": ("posed.landmarks.roi", "Roi"),
    "DetectorOutputs": ("posed.landmarks.runtime", "DetectorOutputs"),
    "LandmarkOutputs": ("posed.landmarks.runtime", "LandmarkOutputs"),
    "OnnxDetector": ("posed.landmarks.runtime", "OnnxDetector"),
    "OnnxLandmarkModel": ("posed.landmarks.runtime", "OnnxLandmarkModel"),
    "SessionSettings": ("posed.landmarks.runtime", "SessionSettings"),
}


def __getattr__(name: str):
    try:
        module, attr = _ORIGIN[name]
    except KeyError:  # also how ``from landmarks import convert`` finds the subpackage
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
