"""Configuration of the 2D landmark stage (config section ``landmarks``)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class LandmarkConfig:
    """BlazePose (MediaPipe Pose, full model) on onnxruntime; defaults are MediaPipe's own."""

    models_dir: str = field(
        default="",
        metadata={"doc": "folder of the converted models; empty = $POSED_MODELS_DIR if set, else "
                         "$XDG_CACHE_HOME/posed/models (~/.cache/posed/models when XDG_CACHE_HOME is unset or relative); "
                         "the service sets POSED_MODELS_DIR=/var/lib/posed/models"},
    )
    threads: int = field(default=1, metadata={"doc": "onnxruntime intra-op threads", "range": (1, 64)})
    min_detection_confidence: float = field(
        default=0.5, metadata={"doc": "detector score threshold (MediaPipe default)", "range": (0.0, 1.0)}
    )
    min_tracking_confidence: float = field(
        default=0.5, metadata={"doc": "pose-presence threshold; below it the detector runs again",
                               "range": (0.0, 1.0)}
    )
    tracking: bool = field(
        default=True, metadata={"doc": "place the next crop from this frame's landmarks and run the detector only "
                                       "when the person is lost (MediaPipe's video mode); false = detect every "
                                       "frame, no smoothing (static-image mode)"}
    )
    smoothing: bool = field(default=True, metadata={"doc": "one-euro smoothing with MediaPipe's parameters"})
    keep_sides: bool = field(
        default=True, metadata={"doc": "put back left and right when BlazePose flips them between two frames of "
                                       "one person faster than anyone can turn (landmarks.sides; false = "
                                       "MediaPipe's labels as they come)"}
    )
    rotate_on_miss: bool = field(
        default=True, metadata={"doc": "when nobody is found, retry the frame rotated by +-90 deg "
                                       "(people lying on the floor)"}
    )
    max_people: int = field(
        default=3, metadata={"doc": "people followed at once, each with their own crop and track id (1 = one "
                                    "person, as MediaPipe's video mode)", "range": (1, 10)}
    )
