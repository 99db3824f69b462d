"""The project's TFLite -> ONNX converter for MediaPipe's pose models and the fetcher behind
``posed models fetch``. Runs only at fetch time (imports ``tflite`` and ``onnx``); the daemon loads the
resulting ONNX files through :mod:`landmarks`.

Public names: ``fetch_models(models_dir, source=None, force=False, say=...) -> FetchResult`` (raises
``FetchError``, which carries the exit status); ``convert(tflite_bytes, name)`` (an ``onnx.ModelProto``),
``CONVERTER_VERSION``, ``SUPPORTED_OPS``, ``ConversionError``, ``UnsupportedOperatorError``; ``densify`` and
``DimMetadata`` (TFLite sparse tensors)."""

from posed.landmarks.convert.converter import (
    CONVERTER_VERSION,
    SUPPORTED_OPS,
    ConversionError,
    UnsupportedOperatorError,
    convert,
)
from posed.landmarks.convert.densify import DimMetadata, densify
from posed.landmarks.convert.fetch import FetchError, FetchResult, fetch_models

__all__ = [
    "CONVERTER_VERSION",
    "SUPPORTED_OPS",
    "ConversionError",
    "DimMetadata",
    "FetchError",
    "FetchResult",
    "UnsupportedOperatorError",
    "convert",
    "densify",
    "fetch_models",
]
