"""Files in and out.

Model files (read without torch, never executing code), ONNX export, and ingestion of robot logs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.io._modelio import (
        FORMAT,
        FORMAT_VERSION,
        READ_VERSIONS,
        load_data_for_model,
        load_inputs_for_model,
        load_model,
        save_model,
    )
    from ipcverify.io._onnx import (
        OPSET,
        ExportInfo,
        OnnxCheck,
        build_onnx,
        check_domain_export,
        check_onnx,
        export_onnx,
        onnx_session,
    )
    from ipcverify.io._torchfile import (
        DamagedArchiveError,
        NeedsTorchError,
        UnsafeContentError,
        read_torch_file,
    )

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "OPSET",
    "READ_VERSIONS",
    "DamagedArchiveError",
    "ExportInfo",
    "NeedsTorchError",
    "OnnxCheck",
    "UnsafeContentError",
    "build_onnx",
    "check_domain_export",
    "check_onnx",
    "export_onnx",
    "load_data_for_model",
    "load_inputs_for_model",
    "load_model",
    "onnx_session",
    "read_torch_file",
    "save_model",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
