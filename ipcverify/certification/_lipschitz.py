"""The Lipschitz constant ``L_g`` of ``g_theta(X) = ||C_theta(x, yhat)(y - c_theta(x, yhat))||`` in ``theta``.

Theorem 1 of the paper needs ``L_g``. Two numbers are computed, and labelled:

* :func:`empirical_lipschitz` -- the largest per-sample gradient norm
  ``||grad_theta g(X_i)||`` over a dataset at the trained ``theta``. It is a
  **lower estimate** of the Lipschitz constant (a maximum over finitely many
  points at one ``theta``), so a Theorem 1 bound computed with it is optimistic,
  not a guarantee.
* :func:`sound_lipschitz` -- an **upper bound** on the Lipschitz constant of
  ``theta -> g_theta(X)`` over the Euclidean parameter ball ``B(theta_hat, r)``
  (``r`` fixed in advance: :data:`DEFAULT_RADIUS`), for every ``X`` in a box
  (by default the bounding box of the data). It propagates norm bounds layer by
  layer and multiplies the result by ``1 + FLOAT_MARGIN`` to cover rounding in
  the float64 arithmetic.

Both take either network kind: the model's engine (:class:`ipcverify.network.Engine`) computes
them for its kind -- for the paper's heads (``"cholesky"``, ``"full"``: one MLP)
:mod:`ipcverify.network._lipschitz_mlp` (derivation: ``proofs/lipschitz.md``), for the default
low-rank ensemble :mod:`ipcverify.network._lipschitz_lowrank` (derivation:
``proofs/lipschitz_lowrank.md``). Only the network's trainable parameters count as ``theta``;
the normalisation buffers (and the ensemble's linear centre stage) are fixed statistics of the
training data. The box and the bound's record are shared
(:mod:`ipcverify.network._lipschitz_ball`, re-exported here).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.network._interface import engine_for, is_network
from ipcverify.network._lipschitz_ball import (
    DEFAULT_RADIUS,
    DataBox,
    LipschitzBound,
    check_radius,
)
from ipcverify.network._modules import Network

FloatArray = NDArray[np.float64]


class Theorem1UnavailableError(InvalidInputError):
    """Theorem 1 (its Lipschitz constant) is not derived for the model's network."""


def theorem1_unavailable(model: IPCModel) -> str | None:
    """Why the Lipschitz constants (hence Theorem 1) cannot be computed for ``model``; None if they can.

    Both network kinds ipcverify builds are covered: the paper's heads
    (``proofs/lipschitz.md``) and the default low-rank ensemble
    (``proofs/lipschitz_lowrank.md``). Only a network of another class is refused.

    Parameters
    ----------
    model : IPCModel
        The model whose network is checked; only the network's class matters (its calibration,
        weights and metadata play no role).

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> theorem1_unavailable(example(config=ModelConfig.recipe("v1", x_dim=2, y_dim=3)).model) is None
    True
    >>> theorem1_unavailable(example(config=ModelConfig(x_dim=2, y_dim=3)).model) is None
    True
    """
    return _unsupported(model.network)


def _unsupported(network: Any) -> str | None:
    if is_network(network):
        return None
    return (
        f"no Lipschitz bound is derived for a network of class {type(network).__name__}: Theorem 1 covers "
        "IPCNetwork (the paper's heads) and LowRankEnsemble (the default); build the network with "
        "ipcverify.network.build_network"
    )


def _require_supported(network: Any) -> Network:
    reason = _unsupported(network)
    if reason is not None:
        raise Theorem1UnavailableError(reason)
    return network  # type: ignore[no-any-return]


@dataclass(frozen=True)
class LipschitzEstimate:
    """A **lower estimate** of ``L_g``: the largest per-sample gradient norm at ``theta_hat``.

    Attributes
    ----------
    value : float
        The estimate.
    n_samples : int
        Samples it was computed on.
    argmax : int
        The sample with the largest gradient norm.
    kind : str
        What the value is, in words (an empirical lower estimate, not a bound).
    """

    value: float
    n_samples: int
    argmax: int
    kind: str = "empirical (lower estimate: max gradient norm over the data at the trained parameters)"

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {"value": self.value, "n_samples": self.n_samples, "argmax": self.argmax, "kind": self.kind}


def per_sample_gradient_norms(
    network: Network,
    x: FloatArray,
    y: FloatArray,
    yhat: FloatArray,
    params: Mapping[str, torch.Tensor] | None = None,
    chunk_size: int = 4096,
    dtype: torch.dtype = torch.float64,
) -> FloatArray:
    """``||grad_theta g(X_i)||`` for every sample, in float64.

    For the paper's heads by ``torch.func`` (vmap of grad); for the low-rank ensemble by
    :func:`ipcverify.network.ensemble_gradient_norms` (the same numbers from one
    backward pass per chunk; its members in ``dtype``, its moment matching in float64).

    Parameters
    ----------
    network : IPCNetwork or LowRankEnsemble
        The network (not modified; a copy in ``dtype`` is used).
    x, y, yhat : arrays (B, d), (B, n), (B, n)
        The samples.
    params : dict, optional
        Parameters to evaluate at (names as in ``network.named_parameters()``);
        default: the network's own.
    chunk_size : int
        Samples per vectorised batch (memory ~ chunk_size * p * 8 bytes).
    dtype : torch.dtype
        Arithmetic of the computation (float64 by default; float32 is about twice as fast).

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import example
    >>> net = example(config=ModelConfig(x_dim=2, y_dim=2, hidden=(4,), param="cholesky")).model.network
    >>> per_sample_gradient_norms(net, np.ones((3, 2)), np.ones((3, 2)), np.zeros((3, 2))).shape
    (3,)
    """
    checked = _require_supported(network)
    return engine_for(checked).gradient_norms(checked, x, y, yhat, params, chunk_size, dtype)


def empirical_lipschitz(
    model: IPCModel, data: PerceptionDataset, chunk_size: int = 4096, dtype: torch.dtype = torch.float32
) -> LipschitzEstimate:
    """Largest ``||grad_theta g||`` over ``data`` at the trained parameters (a lower estimate of ``L_g``).

    Computed in float32 by default (the network's own precision; relative error ~1e-6,
    immaterial for an estimate); pass ``dtype=torch.float64`` for more digits.

    Parameters
    ----------
    model : IPCModel
        The trained model.
    data : PerceptionDataset
        The samples (the training data for Theorem 1).
    chunk_size : int
        Samples per batch of per-sample gradients.
    dtype : torch.dtype
        Precision of the computation.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> m = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model
    >>> est = empirical_lipschitz(m, example(100, seed=0).data)
    >>> est.value > 0, est.n_samples
    (True, 100)
    """
    net = _require_supported(model.network)
    norms = model.engine.gradient_norms(net, data.x, data.y, data.yhat, None, chunk_size, dtype)
    if not np.isfinite(norms).all():
        raise InvalidInputError("a per-sample gradient is not finite; the network output overflowed")
    i = int(np.argmax(norms))
    return LipschitzEstimate(value=float(norms[i]), n_samples=len(norms), argmax=i)


def sound_lipschitz(
    model: IPCModel, box: DataBox | PerceptionDataset, radius: float = DEFAULT_RADIUS
) -> LipschitzBound:
    """Upper bound on the Lipschitz constant of ``theta -> g_theta(X)`` over a ball and a box.

    Valid for every ``theta`` with ``||theta - theta_hat||_2 <= radius`` (all trainable
    parameters stacked) and every ``X = (x, y, yhat)`` in ``box``. See
    ``proofs/lipschitz.md`` for the derivation (the paper's heads) and
    ``proofs/lipschitz_lowrank.md`` for the default ensemble
    (:func:`ipcverify.network.sound_lipschitz_lowrank`).

    Parameters
    ----------
    model : IPCModel
        The trained model (its calibration is irrelevant: ``g`` is the raw score).
    box : DataBox or PerceptionDataset
        The box of ``X`` (a dataset is replaced by its bounding box).
    radius : float
        Radius ``r >= 0`` of the parameter ball; fix it before looking at the data.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.network import ModelConfig
    >>> m = example(config=ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky")).model
    >>> ds = example(100, seed=0).data
    >>> sound_lipschitz(m, ds).value >= empirical_lipschitz(m, ds).value
    True
    """
    radius = check_radius(radius)
    if isinstance(box, PerceptionDataset):
        box = DataBox.from_dataset(box)
    net = _require_supported(model.network)
    return model.engine.sound_lipschitz(net, box, radius)
