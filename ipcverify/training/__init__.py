"""Training an IPC network.

The loop, the paper's hinge objective and ours, the low-rank recipe and the held-out selection of
the paper's hyperparameters.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.training._objectives import TrainConfig
    from ipcverify.training._train import train

__all__ = [
    "TrainConfig",
    "train",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
