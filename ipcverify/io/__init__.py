"""Files in and out.

Model files (read without torch, never executing code), ONNX export, and ingestion of robot logs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.io._modelio import (
        FORMAT_VERSION,
        load_data_for_model,
        load_inputs_for_model,
        load_model,
        save_model,
    )
    from ipcverify.io._onnx import (
        ExportInfo,
        OnnxCheck,
        build_onnx,
        check_onnx,
        export_onnx,
        onnx_session,
    )
    from ipcverify.io._torchfile import (
        DamagedArchiveError,
        NeedsTorchError,
        UnsafeContentError,
    )

__all__ = [
    "FORMAT_VERSION",
    "DamagedArchiveError",
    "ExportInfo",
    "NeedsTorchError",
    "OnnxCheck",
    "UnsafeContentError",
    "build_onnx",
    "check_onnx",
    "export_onnx",
    "load_data_for_model",
    "load_inputs_for_model",
    "load_model",
    "onnx_session",
    "save_model",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
