"""The choice of a network's engine: :func:`engine_for`, the one place the network kind is chosen.

Every kind's float64 engine of record (:class:`~ipcverify.network.InferenceEngine`,
:class:`~ipcverify.network.LowRankEngine`) inherits the engine interface,
:class:`~ipcverify.network.Engine` (defined in ``ipcverify.network._kind``); the rest of
ipcverify uses that interface alone: it never asks which kind a network is.

Examples
--------
>>> import numpy as np
>>> from ipcverify.network import ModelConfig
>>> from ipcverify import example
>>> eng = engine_for(example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,))).model.network)
>>> isinstance(eng, Engine), type(eng).__name__
(True, 'LowRankEngine')
>>> center, shape = eng.single_values(np.zeros(5))
>>> len(center), len(shape)
(3, 9)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify.network._engine import InferenceEngine
from ipcverify.network._kind import Engine
from ipcverify.network._lowrank_engine import LowRankEngine
from ipcverify.network._weights import NetworkWeights, weights_and_network

if TYPE_CHECKING:
    from ipcverify.network._modules import Network


def is_network(obj: object) -> bool:
    """Whether ``obj`` is a torch network of a kind ipcverify builds (so an engine exists for it).

    Imports torch only if its module is already loaded (an object cannot be a network otherwise).

    Examples
    --------
    >>> is_network(object())
    False
    """
    import sys

    if "ipcverify.network._modules" not in sys.modules:
        return False
    from ipcverify.network._modules import IPCNetwork, LowRankEnsemble

    return isinstance(obj, (IPCNetwork, LowRankEnsemble))


def engine_for(source: Network | NetworkWeights) -> Engine:
    """The float64 engine of record for a network or its weights (the one switch on the network kind).

    Parameters
    ----------
    source : Network or NetworkWeights
        A torch network (its weights are extracted) or its weights; a low-rank config gives a
        :class:`LowRankEngine`, the paper's heads an :class:`InferenceEngine`.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> w = example(config=ModelConfig(x_dim=1, y_dim=2, hidden=(4,), members=2)).model.weights
    >>> type(engine_for(w)).__name__
    'LowRankEngine'
    """
    weights = weights_and_network(source)[0]
    if weights.config.lowrank:
        return LowRankEngine.from_weights(weights)
    return InferenceEngine.from_weights(weights)
