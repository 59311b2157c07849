"""One query at a time, fast: (x, yhat) -> calibrated ellipsoid -> landing decision.

A controller asks the contract one question per camera frame. :class:`IPCQuery`
answers it with as little per-call overhead as the sound answer allows:

* :meth:`IPCQuery.ellipsoid` evaluates the model's float64 engine
  (:mod:`ipcverify.inference`, the same weights and the same arithmetic as
  :meth:`~ipcverify.model.IPCModel.predict`) on one query and applies the
  calibration. No :class:`~ipcverify.sets.Ellipsoid` is built, so there is no
  validation SVD on the hot path; the returned centre and shape are plain arrays.
* :meth:`IPCQuery.decide` turns the ellipsoid into the landing decision of record.
  A float pre-check computes the bounding box of the ellipsoid; if the box clearly
  does not fit the target (by more than a relative margin of ``1e-9``) the answer is
  *reject* at once -- rejecting is always safe, the controller only measures again.
  Otherwise the exact :func:`ipcverify.landing.landing_decision` decides, so
  **every accept is backed by an exact proof** (Proposition 1,
  ``proofs/proposition1.md``). Accepting queries therefore cost one exact proof
  (about a millisecond); rejecting ones cost a few microseconds.
* :meth:`IPCQuery.decide_float` is the float decision alone (the same rule as
  :func:`ipcverify.landing.landing_accept_float`): fast in every case, **not a proof**.

Examples
--------
>>> import numpy as np
>>> from ipcverify.model import IPCModel, IPCNetwork, ModelConfig
>>> q = IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,)))))
>>> center, shape = q.ellipsoid(np.zeros(2), np.zeros(3))
>>> center.shape, shape.shape
((3,), (3, 3))
>>> d = q.decide(np.zeros(2), np.zeros(3))
>>> d.accept, d.proven      # an untrained network's sets are far too large to land on
(False, False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.calibration import GlobalCalibration
from ipcverify.containment import Box
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.inference import LOGDIAG_CLAMP, InferenceEngine
from ipcverify.landing import LANDING_TARGET, LandingDecision, landing_decision
from ipcverify.model import IPCModel
from ipcverify.sets import Ellipsoid

__all__ = ["PRECHECK_MARGIN", "QueryDecision", "IPCQuery"]

FloatArray = NDArray[np.float64]

#: Relative margin by which the float pre-check must fail before a query is rejected
#: without the exact proof (anything closer goes to :func:`landing_decision`).
PRECHECK_MARGIN = 1e-9


@dataclass(frozen=True, eq=False, slots=True)
class QueryDecision:
    """The answer to one query.

    Attributes
    ----------
    center : ndarray, shape (n,)
        Centre of the (calibrated) ellipsoid.
    shape : ndarray, shape (n, n)
        Shape matrix ``C`` of ``E = {y : ||C (y - c)|| <= 1}`` (calibration applied).
    accept : bool
        Land on this measurement. From :meth:`IPCQuery.decide` it is True only if
        ``proof`` is an exact PROVEN landing decision.
    turnoff : ndarray, shape (3,)
        Turn-off point ``P``: the exact one (``P_z`` rounded up) when ``proof`` is
        given, else the float ``[c_x, c_y, c_z + h_z]``.
    proof : LandingDecision or None
        The exact decision, when it was computed (pre-check passed).
    proven : bool
        ``accept`` is backed by an exact proof.
    """

    center: FloatArray
    shape: FloatArray
    accept: bool
    turnoff: FloatArray
    proof: LandingDecision | None = None
    proven: bool = field(init=False)

    def __post_init__(self) -> None:
        if self.proof is not None and self.accept != self.proof.accept:
            raise SetError("a decision with a proof must accept exactly when the proof does")
        object.__setattr__(self, "proven", bool(self.accept and self.proof is not None))


def _half_widths_3(C: FloatArray) -> tuple[float, float, float]:
    """``sqrt(((C^T C)^{-1})_ii)`` = norms of the rows of ``C^{-1}`` for a 3x3 ``C`` (float)."""
    (a, b, c), (d, e, f), (g, h, i) = C.tolist()
    A, B, Cc = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * Cc
    if not (math.isfinite(det) and det != 0.0):
        return (math.inf, math.inf, math.inf)
    # rows of adj(C) (= columns of the cofactor matrix), i.e. rows of C^{-1} times det
    r0 = (A, -(b * i - c * h), b * f - c * e)
    r1 = (B, a * i - c * g, -(a * f - c * d))
    r2 = (Cc, -(a * h - b * g), a * e - b * d)
    ad = abs(det)
    return tuple(math.sqrt(u * u + v * v + w * w) / ad for u, v, w in (r0, r1, r2))  # type: ignore[return-value]


@dataclass(frozen=True, eq=False)
class IPCQuery:
    """Low-latency single queries of an IPC, with the landing decision of Proposition 1.

    Parameters
    ----------
    model : IPCModel
        A trained model, calibrated or not (the raw network's sets are used if not).
    target : Box
        The landing target ``G`` (default: the paper's :data:`~ipcverify.landing.LANDING_TARGET`).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.model import IPCModel, IPCNetwork, ModelConfig
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(8,))))
    >>> c, C = IPCQuery(m).ellipsoid([0.0, 1.0], [0.1, 0.2, 0.3])
    >>> bool(np.allclose(C, m.predict([0.0, 1.0], [0.1, 0.2, 0.3]).shapes[0]))
    True
    """

    model: IPCModel
    target: Box = LANDING_TARGET

    def __post_init__(self) -> None:
        if not isinstance(self.model, IPCModel):
            raise InvalidInputError(f"IPCQuery needs an IPCModel; got {type(self.model).__name__}")
        if not isinstance(self.target, Box) or self.target.dim != 3:
            raise SetError("the landing target must be a 3-D Box")
        eng: InferenceEngine = self.model.engine
        cal = self.model.calibration
        scale = float(cal.threshold.scale) if isinstance(cal, GlobalCalibration) else None
        cfg = self.model.config
        object.__setattr__(self, "_engine", eng)
        object.__setattr__(self, "_scale", scale)
        object.__setattr__(self, "_d", cfg.x_dim)
        object.__setattr__(self, "_n", cfg.y_dim)
        object.__setattr__(self, "_full", cfg.param == "full")
        object.__setattr__(self, "_offset", cfg.center == "offset")
        object.__setattr__(self, "_flat_tril", eng.tril_rows * cfg.y_dim + eng.tril_cols)
        object.__setattr__(self, "_flat_diag", np.arange(cfg.y_dim) * (cfg.y_dim + 1))
        object.__setattr__(self, "_lower", [float(v) for v in self.target.lower])
        object.__setattr__(self, "_upper", [float(v) for v in self.target.upper])

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
            shape /= float(self.model.calibration.scale_factors(xa[None], ya[None])[0])
        return center, shape

    # ------------------------------------------------------------------ decision
    def _float_turnoff_and_fit(self, center: FloatArray, shape: FloatArray) -> tuple[FloatArray, float]:
        """Float turn-off point and the smallest relative slack of the box test (< 0: does not fit)."""
        if self._n != 3:  # type: ignore[attr-defined]
            raise SetError(f"the landing decision needs a 3-D ellipsoid; this model has n = {self._n}")  # type: ignore[attr-defined]
        h = _half_widths_3(shape)
        c = center.tolist()
        lo, up = self._lower, self._upper  # type: ignore[attr-defined]
        p = [c[0], c[1], c[2] + h[2]]
        worst = math.inf
        for i in range(3):
            upper_slack = (p[i] - lo[i]) - (c[i] + h[i])  # box face P - G.lower
            lower_slack = (c[i] - h[i]) - (p[i] - up[i])  # box face P - G.upper
            size = 1.0 + abs(p[i]) + abs(c[i]) + h[i] + abs(lo[i]) + abs(up[i])
            worst = min(worst, upper_slack / size, lower_slack / size)
        if not math.isfinite(worst):
            worst = -math.inf
        return np.array(p), worst

    def decide(self, x: ArrayLike, yhat: ArrayLike) -> QueryDecision:
        """Query -> ellipsoid -> landing decision; every accept is exactly proven.

        Returns
        -------
        QueryDecision
            ``accept`` is True only when :func:`~ipcverify.landing.landing_decision`
            PROVES that the turn-off point is safe for every ``y`` in the ellipsoid.

        Raises
        ------
        SetError
            If the model's ``n`` is not 3 (the landing target is 3-D).
        """
        center, shape = self.ellipsoid(x, yhat)
        return self.decide_ellipsoid(center, shape)

    def decide_ellipsoid(self, center: FloatArray, shape: FloatArray) -> QueryDecision:
        """The landing decision for one ellipsoid given as arrays ``c`` (3,) and ``C`` (3, 3).

        The float pre-check rejects when the bounding box misses the target by more than
        :data:`PRECHECK_MARGIN` (relative); otherwise the exact
        :func:`~ipcverify.landing.landing_decision` decides.

        Examples
        --------
        >>> import numpy as np
        >>> from ipcverify.model import IPCModel, IPCNetwork, ModelConfig
        >>> q = IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=1, y_dim=3, hidden=(4,)))))
        >>> d = q.decide_ellipsoid(np.zeros(3), np.diag([40.0, 40.0, 80.0]))
        >>> d.accept, d.proven, d.turnoff.tolist()
        (True, True, [0.0, 0.0, 0.0125])
        >>> q.decide_ellipsoid(np.zeros(3), np.diag([10.0, 40.0, 80.0])).proof is None  # clear reject
        True
        """
        p, worst = self._float_turnoff_and_fit(center, shape)
        if worst < -PRECHECK_MARGIN:
            return QueryDecision(center, shape, False, p)
        proof = landing_decision(Ellipsoid(center, shape), self.target)
        return QueryDecision(center, shape, proof.accept, proof.turnoff.copy(), proof)

    def decide_float(self, x: ArrayLike, yhat: ArrayLike) -> QueryDecision:
        """Query -> ellipsoid -> float landing decision (fast; **not a proof**).

        The rule of :func:`~ipcverify.landing.landing_accept_float`; near the
        threshold it may differ from the exact decision. It accepts exactly when
        :meth:`decide`'s pre-check passes (float slack >= ``-PRECHECK_MARGIN``, so that the
        z face, which touches ``P`` by construction, is not lost to rounding). Use
        :meth:`decide` when the answer steers the vehicle.
        """
        center, shape = self.ellipsoid(x, yhat)
        p, worst = self._float_turnoff_and_fit(center, shape)
        return QueryDecision(center, shape, worst >= -PRECHECK_MARGIN, p)

    def __repr__(self) -> str:
        cal = "calibrated" if self.model.calibration is not None else "uncalibrated"
        return f"IPCQuery(x_dim={self._d}, y_dim={self._n}, {cal})"  # type: ignore[attr-defined]
