"""The project's TFLite -> ONNX converter for MediaPipe's pose models and the fetcher behind
``posed models fetch``. Runs only at fetch time (imports ``tflite`` and ``onnx``); the daemon loads the
resulting ONNX files through :mod:`landmarks.models`."""

from landmarks.convert.converter import (
    CONVERTER_VERSION,
    SUPPORTED_OPS,
    ConversionError,
    UnsupportedOperatorError,
    convert,
)
from landmarks.convert.densify import DimMetadata, densify

__all__ = [
    "CONVERTER_VERSION",
    "SUPPORTED_OPS",
    "ConversionError",
    "DimMetadata",
    "UnsupportedOperatorError",
    "convert",
    "densify",
]
