"""The inverse perception contract: :class:`IPCModel`, a trained network with its calibration.

An :class:`IPCModel` holds the network's weights (:class:`~ipcverify.network.NetworkWeights`,
NumPy), its calibration and its domain of validity, and evaluates its sets with the float64
engine of record (:class:`ipcverify.network.Engine`, from :func:`ipcverify.network.engine_for`:
:mod:`ipcverify.network._engine` for the paper's heads, :mod:`ipcverify.network._lowrank_engine`
for the default ensemble). It is built from a torch network
(:mod:`ipcverify.network._modules`, after training) or from weights read from a file
(:func:`ipcverify.io.load_model`); in the second case torch is imported only if
:attr:`IPCModel.network` is asked for (training, the sound Lipschitz bound, the ONNX export),
so that predicting, calibrating and monitoring run without it.

``IPCNetwork``, ``Network`` and ``build_network`` live in :mod:`ipcverify.network._modules`; importing
them from here still works (and imports torch).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ipcverify.calibration._protocol import Calibration
from ipcverify.contract._guarded import Predictions, predict_sets
from ipcverify.data._dataset import PerceptionInputs, query_rows
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.guard._domain import DomainModel
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._interface import engine_for
from ipcverify.network._kind import Engine
from ipcverify.network._nonsingular import checked_ellipsoid
from ipcverify.network._weights import NetworkWeights, weights_and_network
from ipcverify.sets._ellipsoid import Ellipsoid

if TYPE_CHECKING:
    from ipcverify.network._modules import Network

FloatArray = NDArray[np.float64]
#: Names that moved to :mod:`ipcverify.network._modules`, still importable from here (they import torch).
_MOVED = ("IPCNetwork", "Network", "build_network")


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        import ipcverify.network._modules as modules

        return getattr(modules, name)
    raise AttributeError(f"module 'ipcverify.contract._model' has no attribute {name!r}")


@dataclass(frozen=True, eq=False)
class IPCModel:
    """A trained inverse perception contract, optionally calibrated.

    Parameters
    ----------
    source : IPCNetwork, LowRankEnsemble or NetworkWeights
        The trained network (put in eval mode), or its weights (as a model file holds them;
        the torch network is then built on first use of :attr:`network`).
    calibration : Calibration, optional
        Scale factors applied to the raw sets; see :mod:`ipcverify.calibration`.
    metadata : mapping
        Plain data recorded with the model (training settings, data hash, history).
    domain : DomainModel, optional
        The domain of validity fitted at calibration (:mod:`ipcverify.guard._domain`): queries it
        flags lie outside what the calibration certificate covers.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify import example
    >>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,))).model
    >>> p = m.predict(np.zeros((4, 2)), np.zeros((4, 3)))
    >>> p.sets.batch_size, p.in_domain.tolist()  # no domain model: every query counts as inside
    (4, [True, True, True, True])
    """

    source: Network | NetworkWeights
    calibration: Calibration | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)
    domain: DomainModel | None = None
    _weights: NetworkWeights = field(init=False, repr=False)
    _network: Network | None = field(init=False, repr=False)
    _engine: Engine = field(init=False, repr=False)

    def __post_init__(self) -> None:
        weights, network = weights_and_network(self.source)
        if network is not None:
            network.eval()
        object.__setattr__(self, "_weights", weights)
        object.__setattr__(self, "_network", network)
        if self.domain is not None and len(self.domain.mean) != self.config.x_dim + self.config.y_dim:
            raise InvalidInputError(
                f"the domain model covers {len(self.domain.mean)} input columns but the network takes "
                f"{self.config.x_dim + self.config.y_dim} (x and yhat); refit it with calibrate"
            )
        object.__setattr__(self, "_engine", engine_for(weights))

    @property
    def network(self) -> Network:
        """The torch network (float32; for training, the Lipschitz bound and the export).

        Built from the weights, and torch imported, on first use if the model was read from a file.
        """
        net = self._network
        if net is None:
            net = self._weights.to_network()
            object.__setattr__(self, "_network", net)
        return net

    @property
    def weights(self) -> NetworkWeights:
        """The network's weights in NumPy (what the engine evaluates and the model file holds)."""
        return self._weights

    @property
    def engine(self) -> Engine:
        """The float64 NumPy evaluation of the network (:class:`ipcverify.network.Engine`: the dense
        :mod:`ipcverify.network._engine` or the ensemble's :mod:`ipcverify.network._lowrank_engine`)."""
        return self._engine

    @property
    def config(self) -> ModelConfig:
        """The network architecture."""
        return self._weights.config

    @property
    def n_parameters(self) -> int:
        """Number of trainable scalar parameters ``p``."""
        return self._weights.n_parameters

    def _check(self, x: Any, yhat: Any) -> tuple[FloatArray, FloatArray]:
        xa, ya = query_rows(x), query_rows(yhat)
        cfg = self.config
        if xa.shape[1:] != (cfg.x_dim,) or ya.shape[1:] != (cfg.y_dim,) or len(xa) != len(ya):
            raise InvalidInputError(
                f"the model expects x of shape (B, {cfg.x_dim}) and yhat of shape (B, {cfg.y_dim}); "
                f"got {xa.shape} and {ya.shape}"
            )
        if not (np.isfinite(xa).all() and np.isfinite(ya).all()):
            raise InvalidInputError("x and yhat must be finite")
        return xa, ya

    def raw_arrays(self, x: Any, yhat: Any, batch_size: int | None = None) -> tuple[FloatArray, FloatArray]:
        """Uncalibrated centres (B, n) and shapes (B, n, n), evaluated in float64.

        All of ipcverify evaluates a trained model through this one path (the model's
        float64 engine, :class:`ipcverify.network.Engine`), so calibration, certificates
        and the controller see exactly the same sets. ``batch_size`` rows are evaluated
        together (default: the engine's, :func:`ipcverify.network.chunk_rows`, which keeps them in cache).
        """
        xa, ya = self._check(x, yhat)
        return self._engine.batch(xa, ya, batch_size)

    def predict_raw(self, x: Any, yhat: Any) -> Ellipsoid:
        """The network's own sets, ignoring any calibration."""
        return checked_ellipsoid(*self.raw_arrays(x, yhat))

    def predict(self, x: Any, yhat: Any, chunk: int | None = None) -> Predictions:
        """The contract's sets with the domain verdict: the documented way to get sets.

        Every query gets its set (calibrated if the model carries a calibration) and an
        ``in_domain`` flag: the calibration's guarantee covers only the queries inside the
        domain of validity fitted at calibration, and a query whose set degenerates is kept,
        marked outside, instead of stopping the batch. ``Predictions.sets`` is the
        :class:`~ipcverify.Ellipsoid` batch, ``Predictions.domain`` the count outside.

        Parameters
        ----------
        x : array_like, shape (B, d) or (d,)
        yhat : array_like, shape (B, n) or (n,)
        chunk : int, optional
            Rows evaluated together (default: a cache-sized chunk).

        Returns
        -------
        Predictions

        Examples
        --------
        >>> from ipcverify import calibrate, example
        >>> ex = example(2000, seed=0)
        >>> parts = ex.data.split((0.0, 0.5, 0.5), seed=0)
        >>> contract = calibrate(ex.model, parts.calibration, epsilon=0.1, delta=0.05)
        >>> p = contract.predict(parts.test.x, parts.test.yhat)
        >>> p.sets.batch_size == len(parts.test), p.in_domain.dtype.name
        (True, 'bool')
        """
        xa, ya = self._check(x, yhat)
        return predict_sets(self, PerceptionInputs(xa, ya, source="queries"), chunk)

    def predict_unguarded(self, x: Any, yhat: Any) -> Ellipsoid:
        """The contract's sets WITHOUT the domain-of-validity test: use :meth:`predict` instead.

        A query outside the domain fitted at calibration gets a set like any other, and that
        set carries no guarantee; nothing here says which queries those are. This path exists
        for code that applies the domain test itself (``certify``, ``evaluate``) and for
        measuring the network alone.

        The shapes are divided by the calibration's scales (as :meth:`Ellipsoid.scaled` does)
        and validated once, by the cheap equivalent of the SVD test
        (:func:`ipcverify.network.checked_ellipsoid`).

        Parameters
        ----------
        x : array_like, shape (B, d) or (d,)
        yhat : array_like, shape (B, n) or (n,)
        """
        xa, ya = self._check(x, yhat)
        centers, shapes = self._engine.batch(xa, ya)
        if self.calibration is not None:
            f = np.asarray(self.calibration.scale_for(xa, ya), dtype=np.float64)
            if f.shape != (len(xa),) or not (np.isfinite(f).all() and (f > 0).all()):
                raise SetError("calibration scale factors must be finite and > 0, one per query")
            shapes /= f[:, None, None]
        try:
            return checked_ellipsoid(centers, shapes)
        except SetError as exc:
            raise SetError(_out_of_domain_message(str(exc), self.domain, xa, ya)) from None

    def raw_scores(self, x: Any, y: Any, yhat: Any) -> FloatArray:
        """Uncalibrated scores ``g = ||C (y - c)||`` (B,) in float64."""
        centers, shapes = self.raw_arrays(x, yhat)
        ya = np.asarray(y, dtype=np.float64).reshape(centers.shape)
        return np.linalg.norm(np.einsum("bij,bj->bi", shapes, ya - centers), axis=1)

    def require_calibration(self) -> Calibration:
        """The calibration, or an :class:`InvalidInputError` saying how to get one.

        Examples
        --------
        >>> from ipcverify import example
        >>> m = example(config=ModelConfig(x_dim=1, y_dim=1, hidden=(2,))).model
        >>> m.require_calibration()  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ipcverify.errors.InvalidInputError: the model is not calibrated: ...
        """
        if self.calibration is None:
            raise InvalidInputError(
                "the model is not calibrated: its raw sets carry no guarantee -- calibrate it on held-out "
                "data first (ipcverify calibrate, or ipcverify.contract.calibrate)"
            )
        return self.calibration

    def with_calibration(
        self, calibration: Calibration | None, domain: DomainModel | None = None
    ) -> IPCModel:
        """A copy of this model carrying ``calibration`` and ``domain`` (the network is shared)."""
        return IPCModel(self.source, calibration, self.metadata, domain)


def _out_of_domain_message(error: str, domain: DomainModel | None, x: FloatArray, yhat: FloatArray) -> str:
    """Blame the input, not the model, when the network's set degenerates far from its data."""
    where = error.split(":", 1)[0].replace("ellipsoid", "input row")
    row = int(where.rsplit(" ", 1)[-1]) if where.rsplit(" ", 1)[-1].isdigit() else None
    where += "" if row is None else " (0-based)"
    far = ""
    if domain is not None and row is not None:
        d = float(domain.distance(x[row : row + 1], yhat[row : row + 1])[0])
        if d > domain.threshold:
            far = (
                f" (its distance to the calibration inputs is {d:.3g}, above the domain threshold "
                f"{domain.threshold:.3g})"
            )
    return (
        f"{where}: the contract's set is degenerate (singular or non-finite shape matrix) for this input, "
        f"which lies outside the domain the contract was trained and calibrated on{far}; the contract "
        "certifies nothing there -- drop such inputs, or retrain and recalibrate on data that covers them"
    )


def network_fingerprint(network: Network | NetworkWeights) -> str:
    """SHA-256 of a network's configuration and state dict (ties a calibration to its network).

    Every member of an ensemble is in the state dict, so every member is hashed. A network and
    its :class:`~ipcverify.network.NetworkWeights` have the same fingerprint.

    Parameters
    ----------
    network : Network or NetworkWeights
        The network, or its weights.

    Examples
    --------
    >>> from ipcverify import example
    >>> len(network_fingerprint(example(config=ModelConfig(x_dim=1, y_dim=1, hidden=(2,))).model.network))
    64
    """
    return NetworkWeights.of(network).fingerprint()
