"""Files in and out.

Model files (read without torch, never executing code), ONNX export, and ingestion of robot logs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.io._modelio import load_model, save_model
    from ipcverify.io._onnx import export_onnx

__all__ = [
    "export_onnx",
    "load_model",
    "save_model",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
