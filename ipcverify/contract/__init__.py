"""The contract.

A network with its calibration and domain (``IPCModel``), the pipeline step that calibrates it, and
guarded batch prediction.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.contract._calibrate import calibrate
    from ipcverify.contract._guarded import Predictions
    from ipcverify.contract._model import IPCModel
    from ipcverify.contract._prediction import monitor_log

__all__ = [
    "IPCModel",
    "Predictions",
    "calibrate",
    "monitor_log",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
