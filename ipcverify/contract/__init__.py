"""The contract.

A network with its calibration and domain (``IPCModel``), the pipeline step that calibrates it, and
guarded batch prediction.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.contract._calibrate import (
        calibrate,
    )
    from ipcverify.contract._model import (
        IPCModel,
        network_fingerprint,
    )
    from ipcverify.contract._prediction import (
        LogMonitoring,
        Predictions,
        monitor_log,
        predict_sets,
        write_predictions,
    )

__all__ = [
    "IPCModel",
    "LogMonitoring",
    "Predictions",
    "calibrate",
    "monitor_log",
    "network_fingerprint",
    "predict_sets",
    "write_predictions",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
