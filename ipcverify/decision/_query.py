"""The one query path: (x, yhat) -> calibrated ellipsoid -> landing decision.

A controller asks the contract one question per camera frame. :class:`IPCQuery` is the
only way a single query becomes a calibrated ellipsoid and a decision, with as little
per-call overhead as the sound answer allows:

* :meth:`IPCQuery.ellipsoid` evaluates the model's float64 engine
  (:mod:`ipcverify.network._engine`, the same weights and the same arithmetic as
  :meth:`~ipcverify.contract.IPCModel.predict`) on one query and applies the
  calibration. No :class:`~ipcverify.sets.Ellipsoid` is built, so there is no
  validation SVD on the hot path; the inputs are checked once, and for ``n = 3`` with the
  Cholesky head the output heads are plain float arithmetic (the default ensemble's engine,
  :mod:`ipcverify.network._lowrank_engine`, has its own one-query path,
  :meth:`~ipcverify.network.LowRankEngine.single_values`: one compiled call,
  :func:`ipcverify.network.lowrank_one`, float64 throughout; its sets equal the batch sets to
  1e-12, tested). The returned
  centre and shape are plain arrays.
* :meth:`IPCQuery.decide` turns the ellipsoid (optionally moved to another frame by the
  caller's ``transform``) into the landing decision of record of
  :class:`ipcverify.decision.LandingRule` against the caller's target box ``G``, after the
  model's domain test (:meth:`ipcverify.guard.DomainModel.contains_one`). **Every answer is
  proven** (Proposition 1, ``proofs/proposition1.md``): in float64 with a rigorous rounding
  bound (``proofs/float_landing.md``), or, inside the rounding band, in exact arithmetic.
  Without a ``transform`` the set stays in Python floats from the engine to the bound
  (:meth:`ipcverify.decision.LandingRule.decide_values`: the same rule on the same numbers).
* :meth:`IPCQuery.decide_float` is the float rule alone: fast in every case, **not a proof**.

Examples
--------
>>> import numpy as np
>>> from ipcverify.network._architecture import ModelConfig
>>> from ipcverify.contract._model import IPCModel
>>> from ipcverify.network._modules import IPCNetwork
>>> from ipcverify.sets._shapes import Box
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

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

import ipcverify.decision._landing_bound as landing_bound
from ipcverify.contract._model import IPCModel
from ipcverify.decision._landing import LandingRule, QueryDecision
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.network._architecture import LOGDIAG_CLAMP
from ipcverify.network._engine import InferenceEngine
from ipcverify.network._lowrank_engine import LowRankEngine
from ipcverify.sets._shapes import Box

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
    >>> from ipcverify.network._architecture import ModelConfig
    >>> from ipcverify.contract._model import IPCModel
    >>> from ipcverify.network._modules import IPCNetwork
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
        object.__setattr__(self, "_shapes", ((cfg.x_dim,), (cfg.y_dim,)))
        object.__setattr__(self, "_full", cfg.param == "full")
        object.__setattr__(self, "_offset", cfg.center == "offset")
        # the low-rank ensemble's engine has its own one-query path (all members at once)
        object.__setattr__(self, "_lowrank", eng if isinstance(eng, LowRankEngine) else None)
        object.__setattr__(self, "_fast3", False)
        if isinstance(eng, InferenceEngine):
            object.__setattr__(self, "_flat_tril", eng.tril_rows * cfg.y_dim + eng.tril_cols)
            object.__setattr__(self, "_flat_diag", np.arange(cfg.y_dim) * (cfg.y_dim + 1))
            # n = 3 with the Cholesky head: the heads in plain floats (see _heads3)
            if cfg.y_dim == 3 and cfg.param != "full":
                object.__setattr__(self, "_fast3", True)
                object.__setattr__(
                    self,
                    "_consts",
                    (eng.sigma.tolist(), eng.inv_sigma.tolist(), eng.y_mean.tolist(), LOGDIAG_CLAMP),
                )
        # compile the one-query kernels here, not on the control loop's first frame
        if isinstance(eng, LowRankEngine):
            eng.prepare()
        if self.model.domain is not None:
            self.model.domain.prepare()
        landing_bound.prepare()  # the landing bound's compiled float tier

    # ----------------------------------------------------------------- ellipsoid
    def _inputs(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Checked 1-D float64 ``x``, ``yhat`` and their concatenation (the model's input row)."""
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(yhat, dtype=np.float64)
        if (xa.shape, ya.shape) != self._shapes:  # type: ignore[attr-defined]
            d, n = self._d, self._n  # type: ignore[attr-defined]
            raise InvalidInputError(
                f"one query needs x of shape ({d},) and yhat of shape ({n},); got {xa.shape} and "
                f"{ya.shape} (use IPCModel.predict for batches)"
            )
        z = np.concatenate((xa, ya))
        # one cheap sum in Python floats when finite (it cannot raise: a huge finite row sums to
        # inf, and then the exact test decides)
        if not math.isfinite(sum(z.tolist())) and not np.isfinite(z).all():
            raise InvalidInputError("x and yhat must be finite")
        return xa, ya, z

    def ellipsoid(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and calibrated shape matrix (n, n) for one query.

        The same sets as ``model.predict(x, yhat)`` (float64 engine, calibration
        applied), without building an :class:`~ipcverify.sets.Ellipsoid`.

        Raises
        ------
        InvalidInputError
            If ``x`` or ``yhat`` has the wrong shape or a non-finite entry.
        """
        return self._sets(*self._inputs(x, yhat))

    def _sets(self, xa: FloatArray, ya: FloatArray, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        values = self._values(xa, ya, z)
        if values is not None:
            return self._arrays(*values)
        eng: InferenceEngine = self._engine  # type: ignore[attr-defined]
        h = z - eng.in_mean
        h *= eng.in_scale
        out = eng.mlp(h)  # the engine's own MLP evaluation (1-D input: one query)
        n = self._n  # type: ignore[attr-defined]
        center = (ya if self._offset else eng.y_mean) + eng.sigma * out[:n]  # type: ignore[attr-defined]
        if self._full:  # type: ignore[attr-defined]
            L = out[n:].reshape(n, n)
        else:
            flat_l = np.zeros(n * n)
            flat_l[self._flat_tril] = out[n:]  # type: ignore[attr-defined]
            diag = out[n:][eng.diag_pos]
            flat_l[self._flat_diag] = np.exp(np.minimum(np.maximum(diag, -LOGDIAG_CLAMP), LOGDIAG_CLAMP))  # type: ignore[attr-defined]
            L = flat_l.reshape(n, n)
        shape = L * eng.inv_sigma
        cal_scale: float | None = self._scale  # type: ignore[attr-defined]
        if cal_scale is not None:
            shape /= cal_scale
        elif self.model.calibration is not None:
            shape /= float(self.model.calibration.scale_for(xa[None], ya[None])[0])
        return center, shape

    def _arrays(self, center: list[float], flat: list[float]) -> tuple[FloatArray, FloatArray]:
        """Centre (n,) and shape (n, n) arrays from Python floats, in one allocation."""
        n: int = self._n  # type: ignore[attr-defined]
        both = np.array(center + flat)
        return both[:n], both[n:].reshape(n, n)

    def _values(
        self, xa: FloatArray, ya: FloatArray, z: FloatArray
    ) -> tuple[list[float], list[float]] | None:
        """Calibrated centre and row-major shape as Python floats, where a float path exists.

        The low-rank ensemble (its engine's :meth:`~ipcverify.network.LowRankEngine.single_values`)
        and the Cholesky head for ``n = 3`` (:meth:`_heads3`); None for the other heads.
        """
        if self._lowrank is not None:  # type: ignore[attr-defined]
            center, flat = self._lowrank.single_values(z)  # type: ignore[attr-defined]
        elif self._fast3:  # type: ignore[attr-defined]
            eng: InferenceEngine = self._engine  # type: ignore[attr-defined]
            h = z - eng.in_mean
            h *= eng.in_scale
            center, flat = self._heads3(eng.mlp(h).tolist(), ya)
        else:
            return None
        scale: float | None = self._scale  # type: ignore[attr-defined]
        if scale is None and self.model.calibration is not None:
            scale = float(self.model.calibration.scale_for(xa[None], ya[None])[0])
        if scale is not None:
            flat = [v / scale for v in flat]
        return center, flat

    def _heads3(self, out: list[float], ya: FloatArray) -> tuple[list[float], list[float]]:
        """Centre and row-major ``L diag(1/sigma)`` for n = 3, Cholesky head, in plain floats.

        The same operations as :meth:`InferenceEngine.batch` (``base + sigma o``; ``exp`` of the
        clamped diagonal; ``L_ij / sigma_j``); only ``math.exp`` may differ from NumPy's ``exp``
        in the last bit.
        """
        o0, o1, o2, l00, l10, l11, l20, l21, l22 = out
        (s0, s1, s2), (i0, i1, i2), y_mean, clamp = self._consts  # type: ignore[attr-defined]
        b0, b1, b2 = ya.tolist() if self._offset else y_mean  # type: ignore[attr-defined]
        center = [b0 + s0 * o0, b1 + s1 * o1, b2 + s2 * o2]
        e00 = math.exp(min(max(l00, -clamp), clamp))
        e11 = math.exp(min(max(l11, -clamp), clamp))
        e22 = math.exp(min(max(l22, -clamp), clamp))
        return center, [e00 * i0, 0.0, 0.0, l10 * i0, e11 * i1, 0.0, l20 * i0, l21 * i1, e22 * i2]

    # ------------------------------------------------------------------ decision
    def _ellipsoid_in_frame(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        if self._n != 3:  # type: ignore[attr-defined]
            raise SetError(f"the landing decision needs a 3-D ellipsoid; this model has n = {self._n}")  # type: ignore[attr-defined]
        xa, ya, z = self._inputs(x, yhat)
        center, shape = self._sets(xa, ya, z)
        if transform is not None:
            center, shape = transform(center, shape)
        return center, shape, z

    def decide(self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None = None) -> QueryDecision:
        """Query -> ellipsoid (-> ``transform``) -> landing decision; every answer is proven.

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
            The decision of :meth:`ipcverify.decision.LandingRule.decide`: ``accept`` is True only
            when the turn-off point is proven safe for every ``y`` in the ellipsoid (float64 with
            a rigorous rounding bound, or exact rational arithmetic). A query the model's domain
            test flags (or whose set is degenerate) is answered ``verdict = OUTSIDE_DOMAIN``,
            never accepted.

        Raises
        ------
        SetError
            If the model's ``n`` is not 3 (the landing target is 3-D).
        """
        if transform is None and self._n == 3:  # type: ignore[attr-defined]
            xa, ya, z = self._inputs(x, yhat)
            values = self._values(xa, ya, z)
            if values is not None:  # no arrays until the answer is known
                domain = self.model.domain
                if domain is not None and not domain.contains_one(z):
                    return self.rule.outside_domain_values(*values)
                return self.rule.decide_values(*values)
        center, shape, z = self._ellipsoid_in_frame(x, yhat, transform)
        domain = self.model.domain
        if domain is not None and not domain.contains_one(z):
            return self.rule.outside_domain(center, shape)
        return self.rule.decide(center, shape)

    def decide_float(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None = None
    ) -> QueryDecision:
        """Query -> ellipsoid -> float landing decision (fast; **not a proof**).

        The rule of :func:`~ipcverify.decision.landing_slack`; near the threshold it may
        differ from the exact decision. Use :meth:`decide` when the answer steers the vehicle.
        """
        if transform is None and self._n == 3:  # type: ignore[attr-defined]
            xa, ya, z = self._inputs(x, yhat)
            values = self._values(xa, ya, z)
            if values is not None:  # Python floats, as decide()
                domain = self.model.domain
                if domain is not None and not domain.contains_one(z):
                    return self.rule.outside_domain_values(*values)
                return self.rule.decide_float_values(*values)
        center, shape, z = self._ellipsoid_in_frame(x, yhat, transform)
        domain = self.model.domain
        if domain is not None and not domain.contains_one(z):
            return self.rule.outside_domain(center, shape)
        return self.rule.decide_float(center, shape)

    def __repr__(self) -> str:
        cal = "calibrated" if self.model.calibration is not None else "uncalibrated"
        return f"IPCQuery(x_dim={self._d}, y_dim={self._n}, {cal})"  # type: ignore[attr-defined]
