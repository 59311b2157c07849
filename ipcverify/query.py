"""The one query path: (x, yhat) -> calibrated ellipsoid -> landing decision.

A controller asks the contract one question per camera frame. :class:`IPCQuery` is the
only way a single query becomes a calibrated ellipsoid and a decision, with as little
per-call overhead as the sound answer allows:

* :meth:`IPCQuery.ellipsoid` evaluates the model's float64 engine
  (:mod:`ipcverify.inference`, the same weights and the same arithmetic as
  :meth:`~ipcverify.model.IPCModel.predict`) on one query and applies the
  calibration. No :class:`~ipcverify.sets.Ellipsoid` is built, so there is no
  validation SVD on the hot path; the returned centre and shape are plain arrays.
* :meth:`IPCQuery.decide` turns the ellipsoid (optionally moved to another frame by the
  caller's ``transform``) into the landing decision of record of
  :class:`ipcverify.landing.LandingRule` against the caller's target box ``G``: clear
  misses are rejected at once (rejecting is always safe: the controller measures again),
  **every accept is backed by an exact proof** (Proposition 1, ``proofs/proposition1.md``).
* :meth:`IPCQuery.decide_float` is the float rule alone: fast in every case, **not a proof**.

Examples
--------
>>> import numpy as np
>>> from ipcverify.architecture import ModelConfig
>>> from ipcverify.model import IPCModel, IPCNetwork
>>> from ipcverify.sets import Box
>>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
>>> q = IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky"))), G)
>>> center, shape = q.ellipsoid(np.zeros(2), np.zeros(3))
>>> center.shape, shape.shape
((3,), (3, 3))
>>> d = q.decide(np.zeros(2), np.zeros(3))
>>> d.accept, d.proven      # an untrained network's sets are far too large to land on
(False, False)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.architecture import LOGDIAG_CLAMP
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.inference import InferenceEngine
from ipcverify.landing import LandingRule, QueryDecision
from ipcverify.lowrank_engine import LowRankEngine
from ipcverify.model import IPCModel
from ipcverify.sets import Box

__all__ = ["IPCQuery", "Transform"]

FloatArray = NDArray[np.float64]
#: Moves an ellipsoid ``(c, C)`` to another frame (e.g. camera -> world) before deciding.
Transform = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True, eq=False)
class IPCQuery:
    """Low-latency single queries of an IPC, with the landing decision of Proposition 1.

    Parameters
    ----------
    model : IPCModel
        A trained model, calibrated or not (the raw network's sets are used if not).
    target : Box
        The landing target ``G`` the decision is taken against (3-D).

    Attributes
    ----------
    rule : LandingRule
        The decision rule for ``target``, also usable on ellipsoids from elsewhere.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.architecture import ModelConfig
    >>> from ipcverify.model import IPCModel, IPCNetwork
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param="cholesky")))
    >>> c, C = IPCQuery(m, Box([-1.0, -1.0, 0.0], [1.0, 1.0, 1.0])).ellipsoid([0.0, 1.0], [0.1, 0.2, 0.3])
    >>> bool(np.allclose(C, m.predict([0.0, 1.0], [0.1, 0.2, 0.3]).shapes[0]))
    True
    """

    model: IPCModel
    target: Box
    rule: LandingRule = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.model, IPCModel):
            raise InvalidInputError(f"IPCQuery needs an IPCModel; got {type(self.model).__name__}")
        if not isinstance(self.target, Box) or self.target.dim != 3:
            raise SetError("the landing target must be a 3-D Box")
        eng = self.model.engine
        cal = self.model.calibration
        groups = None if cal is None else cal.groups()
        # one calibrated group: a constant scale, looked up once instead of per query
        scale = float(groups[0].scale) if groups is not None and len(groups) == 1 else None
        cfg = self.model.config
        object.__setattr__(self, "rule", LandingRule(self.target))
        object.__setattr__(self, "_engine", eng)
        object.__setattr__(self, "_scale", scale)
        object.__setattr__(self, "_d", cfg.x_dim)
        object.__setattr__(self, "_n", cfg.y_dim)
        object.__setattr__(self, "_full", cfg.param == "full")
        object.__setattr__(self, "_offset", cfg.center == "offset")
        # the low-rank ensemble's engine has its own one-query path (all members at once)
        object.__setattr__(self, "_lowrank", eng if isinstance(eng, LowRankEngine) else None)
        if isinstance(eng, InferenceEngine):
            object.__setattr__(self, "_flat_tril", eng.tril_rows * cfg.y_dim + eng.tril_cols)
            object.__setattr__(self, "_flat_diag", np.arange(cfg.y_dim) * (cfg.y_dim + 1))

    # ----------------------------------------------------------------- ellipsoid
    def _inputs(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(yhat, dtype=np.float64)
        d, n = self._d, self._n  # type: ignore[attr-defined]
        if xa.shape != (d,) or ya.shape != (n,):
            raise InvalidInputError(
                f"one query needs x of shape ({d},) and yhat of shape ({n},); got {xa.shape} and "
                f"{ya.shape} (use IPCModel.predict for batches)"
            )
        return xa, ya

    def ellipsoid(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and calibrated shape matrix (n, n) for one query.

        The same sets as ``model.predict(x, yhat)`` (float64 engine, calibration
        applied), without building an :class:`~ipcverify.sets.Ellipsoid`.

        Raises
        ------
        InvalidInputError
            If ``x`` or ``yhat`` has the wrong shape or a non-finite entry.
        """
        xa, ya = self._inputs(x, yhat)
        if self._lowrank is not None:  # type: ignore[attr-defined]
            return self._lowrank_ellipsoid(xa, ya)
        eng: InferenceEngine = self._engine  # type: ignore[attr-defined]
        n: int = self._n  # type: ignore[attr-defined]
        z = np.concatenate((xa, ya))
        if not np.isfinite(z).all():
            raise InvalidInputError("x and yhat must be finite")
        z -= eng.in_mean
        z *= eng.in_scale
        out = eng.mlp(z)  # the engine's own MLP evaluation (1-D input: one query)
        center = (ya if self._offset else eng.y_mean) + eng.sigma * out[:n]  # type: ignore[attr-defined]
        if self._full:  # type: ignore[attr-defined]
            L = out[n:].reshape(n, n)
        else:
            flat = np.zeros(n * n)
            flat[self._flat_tril] = out[n:]  # type: ignore[attr-defined]
            diag = out[n:][eng.diag_pos]
            flat[self._flat_diag] = np.exp(np.minimum(np.maximum(diag, -LOGDIAG_CLAMP), LOGDIAG_CLAMP))  # type: ignore[attr-defined]
            L = flat.reshape(n, n)
        shape = L * eng.inv_sigma
        scale: float | None = self._scale  # type: ignore[attr-defined]
        if scale is not None:
            shape /= scale
        elif self.model.calibration is not None:
            shape /= float(self.model.calibration.scale_for(xa[None], ya[None])[0])
        return center, shape

    def _lowrank_ellipsoid(self, xa: FloatArray, ya: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`ellipsoid` for the low-rank ensemble: its engine's one-query path, then the calibration."""
        if not (np.isfinite(xa).all() and np.isfinite(ya).all()):
            raise InvalidInputError("x and yhat must be finite")
        eng: LowRankEngine = self._lowrank  # type: ignore[attr-defined]
        center, shape = eng.single(xa, ya)
        scale: float | None = self._scale  # type: ignore[attr-defined]
        if scale is not None:
            shape /= scale
        elif self.model.calibration is not None:
            shape /= float(self.model.calibration.scale_for(xa[None], ya[None])[0])
        return center, shape

    # ------------------------------------------------------------------ decision
    def _ellipsoid_in_frame(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None
    ) -> tuple[FloatArray, FloatArray]:
        if self._n != 3:  # type: ignore[attr-defined]
            raise SetError(f"the landing decision needs a 3-D ellipsoid; this model has n = {self._n}")  # type: ignore[attr-defined]
        center, shape = self.ellipsoid(x, yhat)
        return (center, shape) if transform is None else transform(center, shape)

    def _in_domain(self, x: ArrayLike, yhat: ArrayLike) -> bool:
        domain = self.model.domain
        if domain is None:
            return True
        xa, ya = self._inputs(x, yhat)
        return domain.contains_one(np.concatenate((xa, ya)))

    def decide(self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None = None) -> QueryDecision:
        """Query -> ellipsoid (-> ``transform``) -> landing decision; every accept is exactly proven.

        Parameters
        ----------
        x, yhat : array_like
            One query, shapes ``(d,)`` and ``(3,)``.
        transform : callable, optional
            Moves the ellipsoid ``(c, C)`` to the frame of the target (e.g. camera -> world)
            before deciding.

        Returns
        -------
        QueryDecision
            ``accept`` is True only when :func:`~ipcverify.landing.landing_decision`
            PROVES that the turn-off point is safe for every ``y`` in the ellipsoid. A query
            the model's domain test flags (or whose set is degenerate) is answered
            ``verdict = OUTSIDE_DOMAIN``, never accepted.

        Raises
        ------
        SetError
            If the model's ``n`` is not 3 (the landing target is 3-D).
        """
        center, shape = self._ellipsoid_in_frame(x, yhat, transform)
        if not self._in_domain(x, yhat):
            return self.rule.outside_domain(center, shape)
        return self.rule.decide(center, shape)

    def decide_float(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None = None
    ) -> QueryDecision:
        """Query -> ellipsoid -> float landing decision (fast; **not a proof**).

        The rule of :func:`~ipcverify.landing.landing_slack`; near the threshold it may
        differ from the exact decision. Use :meth:`decide` when the answer steers the vehicle.
        """
        center, shape = self._ellipsoid_in_frame(x, yhat, transform)
        if not self._in_domain(x, yhat):
            return self.rule.outside_domain(center, shape)
        return self.rule.decide_float(center, shape)

    def __repr__(self) -> str:
        cal = "calibrated" if self.model.calibration is not None else "uncalibrated"
        return f"IPCQuery(x_dim={self._d}, y_dim={self._n}, {cal})"  # type: ignore[attr-defined]
