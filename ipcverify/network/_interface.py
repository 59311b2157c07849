"""The engine interface: what every network kind's float64 engine of record provides.

A network kind (the paper's heads, :class:`~ipcverify.network.IPCNetwork`; the default
low-rank ensemble, :class:`~ipcverify.network.LowRankEnsemble`) is evaluated everywhere by
its float64 NumPy engine (:class:`~ipcverify.network.InferenceEngine`,
:class:`~ipcverify.network.LowRankEngine`). Both satisfy :class:`Engine`, and the rest of
ipcverify uses that interface alone: it never asks which kind a network is.
:func:`engine_for` is the one place the kind is chosen.

Examples
--------
>>> from ipcverify.network._architecture import ModelConfig
>>> from ipcverify.network._modules import build_network
>>> eng = engine_for(build_network(ModelConfig(x_dim=2, y_dim=3, hidden=(8,))))
>>> isinstance(eng, Engine), type(eng).__name__
(True, 'LowRankEngine')
>>> center, shape = eng.single_values(np.zeros(5))
>>> len(center), len(shape)
(3, 9)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ipcverify.network._architecture import ModelConfig
from ipcverify.network._engine import InferenceEngine
from ipcverify.network._lowrank_engine import LowRankEngine
from ipcverify.network._weights import NetworkWeights, weights_and_network

if TYPE_CHECKING:
    from ipcverify.network._lipschitz_ball import DataBox, LipschitzBound
    from ipcverify.network._modules import Network

FloatArray = NDArray[np.float64]
#: ``node(op, inputs, output_name, **attributes) -> output_name`` (adds an ONNX node)
NodeFn = Callable[..., str]
#: ``const(name, value, dtype=graph dtype) -> name`` (adds an ONNX initializer)
ConstFn = Callable[..., str]


@runtime_checkable
class Engine(Protocol):
    """The float64 evaluation of record of one network kind.

    Batch sets (:meth:`batch`), one query (:meth:`single_values`, the values the decision of
    record uses), :meth:`prepare`, the ONNX graph (:meth:`onnx_nodes`) and the Lipschitz
    constant of the score in the parameters as Theorem 1 uses it (:meth:`gradient_norms`, the
    empirical estimate; :meth:`sound_lipschitz`, the sound bound).
    """

    @property
    def config(self) -> ModelConfig:
        """The architecture evaluated."""
        ...

    @property
    def in_mean(self) -> FloatArray:
        """Mean of the input row ``concat(x, yhat)`` (standardisation)."""
        ...

    @property
    def in_scale(self) -> FloatArray:
        """Reciprocal standard deviation of the input row (standardisation)."""
        ...

    @property
    def chunk(self) -> int:
        """Rows :meth:`batch` evaluates together by default (they stay in cache)."""
        ...

    def batch(
        self, x: FloatArray, yhat: FloatArray, chunk: int | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centres (B, n) and shape matrices (B, n, n) for validated float64 inputs."""
        ...

    def single(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centre (n,) and shape (n, n) for one query given as 1-D float64 arrays."""
        ...

    def single_values(self, z: FloatArray) -> tuple[list[float], list[float]]:
        """Uncalibrated centre (n floats) and row-major shape (n * n floats) for one input row.

        ``z`` is ``concat(x, yhat)`` (1-D float64, C-contiguous, as :func:`numpy.concatenate`
        returns it; not modified). The numbers of :meth:`batch` for that row, up to the summation
        order of matrix products and libm's ``exp`` for NumPy's.
        """
        ...

    def prepare(self) -> None:
        """Compile or warm up the one-query path now, so that the first query costs what the others do."""
        ...

    def float64_layers(self, z: FloatArray) -> Any:
        """The network's layers alone on standardised rows ``z`` (B, d + n): the float64 work of every set."""
        ...

    def onnx_nodes(
        self, z: str, node: NodeFn, const: ConstFn, scale: float | None, dtype: type[np.floating[Any]]
    ) -> None:
        """Add the ONNX nodes from the standardised inputs ``z`` to the outputs ``center`` and ``shape``."""
        ...

    def gradient_norms(
        self,
        network: Network,
        x: FloatArray,
        y: FloatArray,
        yhat: FloatArray,
        params: Mapping[str, Any] | None,
        chunk_size: int,
        dtype: Any,
    ) -> FloatArray:
        """``||grad_theta g(X_i)||`` per sample for ``network`` (of this engine's kind), in float64."""
        ...

    def sound_lipschitz(self, network: Network, box: DataBox, radius: float) -> LipschitzBound:
        """A sound upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` over a ball and a box."""
        ...


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
    >>> from ipcverify.network._weights import state_layout
    >>> cfg = ModelConfig(x_dim=1, y_dim=2, hidden=(4,), members=2)
    >>> w = NetworkWeights(cfg, {k: np.ones(s, t) for k, (s, t, _) in state_layout(cfg).items()})
    >>> type(engine_for(w)).__name__
    'LowRankEngine'
    """
    weights = weights_and_network(source)[0]
    if weights.config.lowrank:
        return LowRankEngine.from_weights(weights)
    return InferenceEngine.from_weights(weights)
