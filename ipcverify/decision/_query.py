"""The one query path: (x, yhat) -> the model's engine -> calibration scale -> domain test.

A controller asks the contract one question per camera frame. :class:`IPCQuery` is the only
way a single query becomes a calibrated ellipsoid, for any output dimension ``n``, with as
little per-call overhead as the sound answer allows:

* the model's float64 engine (:class:`ipcverify.network.Engine`, the same weights and the
  same arithmetic as :meth:`~ipcverify.contract.IPCModel.predict`) evaluates the query's input
  row once (:meth:`~ipcverify.network.Engine.single_values`: for the default ensemble one
  compiled call, :func:`ipcverify.network.lowrank_one`; for ``n = 3`` with the Cholesky head
  plain float arithmetic; its sets equal the batch sets to 1e-12, tested);
* the calibration's scale divides the shape (one calibrated group: a constant looked up once);
* the model's domain test (:meth:`ipcverify.guard.DomainModel.contains_one`) says whether the
  calibration's guarantee covers the query.

No :class:`~ipcverify.sets.Ellipsoid` is built, so there is no validation SVD on the hot path;
the inputs are checked once. :meth:`IPCQuery.evaluate` returns the set and the domain flag as
arrays; :meth:`IPCQuery.values` the same as Python floats (what a decision rule reads);
:meth:`IPCQuery.ellipsoid` the set alone. The landing decision of record wraps it:
:class:`ipcverify.decision.LandingQuery`.

Examples
--------
>>> from ipcverify import example
>>> q = IPCQuery(example(config=ModelConfig(x_dim=2, y_dim=2, hidden=(8,), param="cholesky")).model)
>>> s = q.evaluate(np.zeros(2), np.zeros(2))
>>> s.center.shape, s.shape.shape, s.in_domain      # a 2-D output; no domain test: every query is in
((2,), (2, 2), True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.calibration._protocol import Calibration
from ipcverify.contract._model import IPCModel
from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain import DomainModel
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._kind import Engine

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False, slots=True)
class QuerySet:
    """One query's calibrated set ``E(center, shape)`` and whether it passed the domain test.

    ``in_domain`` is False when the model's domain of validity flags the query: its set is then
    outside what the calibration certificate covers (True without a domain test).

    Attributes
    ----------
    center : ndarray, shape (n,)
        The set's centre ``c`` (float64, in the units of ``y``).
    shape : ndarray, shape (n, n)
        Its shape matrix ``C``, divided by the calibration scale (the raw network's if the model
        is not calibrated): ``E = {y : ||C (y - c)|| <= 1}``.
    in_domain : bool
        The query passed the model's domain-of-validity test (always True without one).
    """

    center: FloatArray
    shape: FloatArray
    in_domain: bool


@dataclass(frozen=True, eq=False)
class IPCQuery:
    """Low-latency single queries of an IPC: engine -> calibration scale -> domain test.

    Parameters
    ----------
    model : IPCModel
        A trained model, calibrated or not (the raw network's sets are used if not), of any
        output dimension.

    Examples
    --------
    >>> from ipcverify import example
    >>> m = example(config=ModelConfig(x_dim=2, y_dim=3, hidden=(8,), members=2)).model
    >>> c, C = IPCQuery(m).ellipsoid([0.0, 1.0], [0.1, 0.2, 0.3])
    >>> bool(np.allclose(C, m.predict_unguarded([0.0, 1.0], [0.1, 0.2, 0.3]).shapes[0]))
    True
    """

    model: IPCModel
    _engine: Engine = field(init=False, repr=False)
    _domain: DomainModel | None = field(init=False, repr=False)
    #: one calibrated group: its constant scale; None otherwise
    _scale: float | None = field(init=False, repr=False)
    #: a calibration by group: its scale is looked up per query (None: a constant or no scale)
    _lookup: Calibration | None = field(init=False, repr=False)
    _d: int = field(init=False, repr=False)
    _n: int = field(init=False, repr=False)
    _shapes: tuple[tuple[int], tuple[int]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.model, IPCModel):
            raise InvalidInputError(f"IPCQuery needs an IPCModel; got {type(self.model).__name__}")
        cal = self.model.calibration
        groups = None if cal is None else cal.groups()
        # one calibrated group: a constant scale, looked up once instead of per query
        scale = float(groups[0].scale) if groups is not None and len(groups) == 1 else None
        cfg: ModelConfig = self.model.config
        d, n = cfg.x_dim, cfg.y_dim
        derived = {
            "_engine": self.model.engine,
            "_domain": self.model.domain,
            "_scale": scale,
            "_lookup": cal if scale is None else None,
            "_d": d,
            "_n": n,
            "_shapes": ((d,), (n,)),
        }
        for name, value in derived.items():
            object.__setattr__(self, name, value)
        # compile the one-query kernels here, not on the control loop's first frame
        self._engine.prepare()
        if self._domain is not None:
            self._domain.prepare()

    def input_row(self, x: ArrayLike, yhat: ArrayLike) -> FloatArray:
        """The checked input row ``concat(x, yhat)`` (1-D float64) of one query.

        Raises
        ------
        InvalidInputError
            If ``x`` or ``yhat`` has the wrong shape or a non-finite entry.
        """
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(yhat, dtype=np.float64)
        if (xa.shape, ya.shape) != self._shapes:
            raise InvalidInputError(
                f"one query needs x of shape ({self._d},) and yhat of shape ({self._n},); got {xa.shape} and "
                f"{ya.shape} (use IPCModel.predict for batches)"
            )
        z = np.concatenate((xa, ya))
        # one cheap sum in Python floats when finite (it cannot raise: a huge finite row sums to
        # inf, and then the exact test decides)
        if not math.isfinite(sum(z.tolist())) and not np.isfinite(z).all():
            raise InvalidInputError("x and yhat must be finite")
        return z

    def _group_scale(self, z: FloatArray) -> float | None:
        """The scale of a calibration by group for this row (None without one)."""
        if self._lookup is None:
            return None
        d = self._d
        return float(self._lookup.scale_for(z[None, :d], z[None, d:])[0])

    def _calibrated(self, z: FloatArray) -> tuple[list[float], list[float]]:
        """Calibrated centre (n floats) and row-major shape (n * n floats) of an input row."""
        center, flat = self._engine.single_values(z)
        scale = self._scale if self._lookup is None else self._group_scale(z)
        if scale is not None:
            flat = [v / scale for v in flat]
        return center, flat

    def values(self, x: ArrayLike, yhat: ArrayLike) -> tuple[list[float], list[float], bool]:
        """Calibrated centre (n floats), row-major shape (n * n floats), and the domain test's answer.

        The numbers of :meth:`ellipsoid` as Python floats (no arrays: what a decision rule such
        as :meth:`ipcverify.decision.LandingRule.decide_values` reads), and whether the query is
        inside the model's domain of validity (True without a domain test).

        Raises
        ------
        InvalidInputError
            If ``x`` or ``yhat`` has the wrong shape or a non-finite entry.
        """
        z = self.input_row(x, yhat)
        center, flat = self._engine.single_values(z)
        scale = self._scale if self._lookup is None else self._group_scale(z)
        if scale is not None:
            flat = [v / scale for v in flat]
        domain = self._domain
        return center, flat, domain is None or domain.contains_one(z)

    def ellipsoid(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and calibrated shape matrix (n, n) for one query (no domain test).

        The same sets as ``model.predict_unguarded(x, yhat)`` (float64 engine, calibration
        applied), without building an :class:`~ipcverify.sets.Ellipsoid`.

        Raises
        ------
        InvalidInputError
            If ``x`` or ``yhat`` has the wrong shape or a non-finite entry.
        """
        return self.arrays(*self._calibrated(self.input_row(x, yhat)))

    def evaluate(self, x: ArrayLike, yhat: ArrayLike) -> QuerySet:
        """The calibrated set of one query and the domain test's answer, as arrays.

        Examples
        --------
        >>> from ipcverify import example
        >>> q = IPCQuery(example(config=ModelConfig(x_dim=1, y_dim=2, hidden=(4,))).model)
        >>> s = q.evaluate([0.5], [0.0, 1.0])
        >>> s.shape.shape, s.in_domain
        ((2, 2), True)
        """
        center, flat, inside = self.values(x, yhat)
        c, C = self.arrays(center, flat)
        return QuerySet(c, C, bool(inside))

    def arrays(self, center: list[float], flat: list[float]) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and shape (n, n) arrays from :meth:`values`' floats, in one allocation."""
        n = self._n
        both = np.array(center + flat)
        return both[:n], both[n:].reshape(n, n)

    def __repr__(self) -> str:
        cal = "calibrated" if self.model.calibration is not None else "uncalibrated"
        return f"IPCQuery(x_dim={self._d}, y_dim={self._n}, {cal})"
