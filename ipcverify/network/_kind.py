"""The engine interface: the base class of every network kind's float64 engine of record.

A network kind (the paper's heads, :class:`~ipcverify.network.IPCNetwork`; the default
low-rank ensemble, :class:`~ipcverify.network.LowRankEnsemble`) is evaluated everywhere by
its float64 NumPy engine (:class:`~ipcverify.network.InferenceEngine`,
:class:`~ipcverify.network.LowRankEngine`). Both inherit :class:`Engine`, and the rest of
ipcverify uses that interface alone: it never asks which kind a network is
(:func:`ipcverify.network.engine_for` is the one place the kind is chosen).

An engine implements the evaluation itself; the members its kind answers with its own modules
(the ONNX graph and the Lipschitz constants) it names, as class constants, by the functions of
its kind (imported on first use: the Lipschitz functions need torch, the graph's caller onnx).
Each such function checks that the network it is given is of its kind.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from importlib import import_module
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np
from numpy.typing import NDArray

from ipcverify.network._weights import NetworkWeights

if TYPE_CHECKING:
    from ipcverify.network._architecture import ModelConfig
    from ipcverify.network._lipschitz_ball import DataBox, LipschitzBound
    from ipcverify.network._modules import Network

FloatArray = NDArray[np.float64]
#: ``node(op, inputs, output_name, **attributes) -> output_name`` (adds an ONNX node)
NodeFn = Callable[..., str]
#: ``const(name, value, dtype=graph dtype) -> name`` (adds an ONNX initializer)
ConstFn = Callable[..., str]


def _function(where: tuple[str, str]) -> Callable[..., Any]:
    module, name = where
    fn: Callable[..., Any] = getattr(import_module(module), name)
    return fn


class Engine(ABC):
    """The float64 evaluation of record of one network kind.

    Batch sets (:meth:`batch`), one query (:meth:`single_values`, the values the decision of
    record uses), :meth:`prepare`, the ONNX graph (:meth:`onnx_nodes`) and the Lipschitz
    constant of the score in the parameters as Theorem 1 uses it (:meth:`gradient_norms`, the
    empirical estimate; :meth:`sound_lipschitz`, the sound bound).

    A subclass (a frozen dataclass) provides the read-only attributes :attr:`config`,
    :attr:`in_mean`, :attr:`in_scale` and :attr:`chunk` (fields or properties), implements the
    evaluation methods, and sets :attr:`ONNX`, :attr:`GRADIENTS` and :attr:`BOUND` to
    ``(module, function)``: the functions :meth:`onnx_nodes`, :meth:`gradient_norms` and
    :meth:`sound_lipschitz` call.
    """

    #: ``f(engine, z, node, const, scale, dtype)``: the graph from the standardised inputs to the outputs
    ONNX: ClassVar[tuple[str, str]]
    #: ``f(network, x, y, yhat, params, chunk_size, dtype)``: per-sample ``||grad_theta g||``
    GRADIENTS: ClassVar[tuple[str, str]]
    #: ``f(network, box, radius)``: the sound bound on the Lipschitz constant of the score in ``theta``
    BOUND: ClassVar[tuple[str, str]]

    #: The architecture evaluated.
    config: ModelConfig
    #: Mean of the input row ``concat(x, yhat)`` (standardisation).
    in_mean: FloatArray
    #: Reciprocal standard deviation of the input row (standardisation).
    in_scale: FloatArray
    #: Rows :meth:`batch` evaluates together by default (they stay in cache).
    chunk: int

    @classmethod
    @abstractmethod
    def from_weights(cls, weights: NetworkWeights) -> Self:
        """The engine of a network's weights (:class:`~ipcverify.network.NetworkWeights`, of this kind)."""

    @classmethod
    def from_network(cls, network: Network) -> Self:
        """The engine of a torch network of this kind (:meth:`from_weights` of its weights)."""
        return cls.from_weights(NetworkWeights.from_network(network))

    @abstractmethod
    def batch(
        self, x: FloatArray, yhat: FloatArray, chunk: int | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centres (B, n) and shape matrices (B, n, n) for validated float64 inputs."""

    @abstractmethod
    def single(self, x: FloatArray, yhat: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centre (n,) and shape (n, n) for one query given as 1-D float64 arrays."""

    @abstractmethod
    def single_values(self, z: FloatArray) -> tuple[list[float], list[float]]:
        """Uncalibrated centre (n floats) and row-major shape (n * n floats) for one input row.

        ``z`` is ``concat(x, yhat)`` (1-D float64, C-contiguous, as :func:`numpy.concatenate`
        returns it; not modified). The numbers of :meth:`batch` for that row, up to the summation
        order of matrix products and libm's ``exp`` for NumPy's.
        """

    @abstractmethod
    def prepare(self) -> None:
        """Compile or warm up the one-query path now, so that the first query costs what the others do."""

    @abstractmethod
    def float64_layers(self, z: FloatArray) -> Any:
        """The network's layers alone on standardised rows ``z`` (B, d + n): the float64 work of every set."""

    def onnx_nodes(
        self, z: str, node: NodeFn, const: ConstFn, scale: float | None, dtype: type[np.floating[Any]]
    ) -> None:
        """Add the ONNX nodes from the standardised inputs ``z`` to the outputs ``center`` and ``shape``."""
        _function(self.ONNX)(self, z, node, const, scale, dtype)

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
        norms: FloatArray = _function(self.GRADIENTS)(network, x, y, yhat, params, chunk_size, dtype)
        return norms

    def sound_lipschitz(self, network: Network, box: DataBox, radius: float) -> LipschitzBound:
        """A sound upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` over a ball and a box."""
        bound: LipschitzBound = _function(self.BOUND)(network, box, radius)
        return bound
