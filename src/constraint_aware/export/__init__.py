"""Deployment formats for robot controllers: the policy as an ONNX model (no torch needed).

The `onnx` package is an optional extra (`pip install 'constraint-aware[onnx]'`); it is imported
only when a model is built, so importing this subpackage costs nothing.
"""

from constraint_aware.export.onnx import (
    INPUT_NAME,
    OUTPUT_NAME,
    build_onnx_model,
    export_onnx,
    onnx_parity,
    random_observations,
    read_onnx_metadata,
)

__all__ = [
    "INPUT_NAME",
    "OUTPUT_NAME",
    "build_onnx_model",
    "export_onnx",
    "onnx_parity",
    "random_observations",
    "read_onnx_metadata",
]
