"""Training an IPC network.

The loop, the paper's hinge objective and ours, the low-rank recipe and the held-out selection of
the paper's hyperparameters.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.training._objectives import (
        Loss,
        NonFiniteLossError,
        Schedule,
        TrainConfig,
        hinge,
        ipc_loss,
        likelihood_loss,
        objective,
    )
    from ipcverify.training._selection import (
        Candidate,
        HingeSelection,
        SelectionRecord,
    )
    from ipcverify.training._train import (
        TrainResult,
        select_hinge,
        train,
    )

__all__ = [
    "Candidate",
    "HingeSelection",
    "Loss",
    "NonFiniteLossError",
    "Schedule",
    "SelectionRecord",
    "TrainConfig",
    "TrainResult",
    "hinge",
    "ipc_loss",
    "likelihood_loss",
    "objective",
    "select_hinge",
    "train",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
