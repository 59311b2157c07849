"""ipcverify: learn and certify inverse perception contracts.

An inverse perception contract (IPC) maps a state ``x`` and a perceived value
``yhat`` to an ellipsoid that contains the true value ``y`` with high probability.
"""

from __future__ import annotations

from ipcverify.errors import (
    DataError,
    InvalidInputError,
    IPCVerifyError,
    ModelFileError,
    SampleSizeError,
    SetError,
)
from ipcverify.sets import Ellipsoid

__version__ = "0.1.0"

__all__ = [
    "DataError",
    "Ellipsoid",
    "IPCVerifyError",
    "InvalidInputError",
    "ModelFileError",
    "SampleSizeError",
    "SetError",
    "__version__",
]
