"""The IPC networks.

Architectures and recipes, the torch modules, their float64 engines of record (one interface,
:class:`Engine`, chosen by :func:`engine_for`: the only switch on the network kind in ipcverify),
compiled kernels, the nonsingularity check, the per-kind Lipschitz bounds and ONNX graphs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.network._architecture import ModelConfig

__all__ = [
    "ModelConfig",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
