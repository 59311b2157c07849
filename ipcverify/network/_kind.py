"""The engine members a network kind answers with its own modules: the ONNX graph and the Lipschitz constants.

Both engines inherit :class:`KindModules` and name, as class constants, the functions of their
kind (imported on first use: the Lipschitz functions need torch, the graph's caller onnx). Each
function checks that the network it is given is of its kind.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

    from ipcverify.network._lipschitz_ball import DataBox, LipschitzBound
    from ipcverify.network._modules import Network

FloatArray = NDArray[np.float64]


def _function(where: tuple[str, str]) -> Callable[..., Any]:
    module, name = where
    fn: Callable[..., Any] = getattr(import_module(module), name)
    return fn


class KindModules:
    """The engine interface's :meth:`onnx_nodes`, :meth:`gradient_norms` and :meth:`sound_lipschitz`.

    A subclass sets :attr:`ONNX`, :attr:`GRADIENTS` and :attr:`BOUND` to ``(module, function)``.
    """

    #: ``f(engine, z, node, const, scale, dtype)``: the graph from the standardised inputs to the outputs
    ONNX: ClassVar[tuple[str, str]]
    #: ``f(network, x, y, yhat, params, chunk_size, dtype)``: per-sample ``||grad_theta g||``
    GRADIENTS: ClassVar[tuple[str, str]]
    #: ``f(network, box, radius)``: the sound bound on the Lipschitz constant of the score in ``theta``
    BOUND: ClassVar[tuple[str, str]]

    def onnx_nodes(
        self, z: str, node: Callable[..., str], const: Callable[..., str], scale: float | None, dtype: Any
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
