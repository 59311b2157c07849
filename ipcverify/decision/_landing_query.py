"""The landing decision of record on the one query path: :class:`LandingQuery` wraps an :class:`IPCQuery`.

:meth:`LandingQuery.decide` takes one query through the model's engine, the calibration scale
and the domain test (:class:`ipcverify.decision.IPCQuery`), optionally moves the ellipsoid to
another frame (the caller's ``transform``), and answers with the landing decision of record of
:class:`ipcverify.decision.LandingRule` against the caller's target box ``G``. **Every answer is
proven** (Proposition 1, ``proofs/proposition1.md``): in float64 with a rigorous rounding bound
(``proofs/float_landing.md``), or, inside the rounding band, in exact arithmetic. Without a
``transform`` the set stays in Python floats from the engine to the bound
(:meth:`ipcverify.decision.LandingRule.decide_values`: the same rule on the same numbers).
A query the domain test flags is answered OUTSIDE_DOMAIN, never accepted.
:meth:`LandingQuery.decide_float` is the float rule alone: fast in every case, **not a proof**.

"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

import ipcverify.decision._landing_bound as landing_bound
from ipcverify.contract._model import IPCModel
from ipcverify.decision._landing import LandingRule, QueryDecision
from ipcverify.decision._query import IPCQuery
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._box import Box

FloatArray = NDArray[np.float64]
#: Moves an ellipsoid ``(c, C)`` to another frame (e.g. camera -> world) before deciding.
Transform = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True, eq=False)
class LandingQuery:
    """The landing decision of Proposition 1 for single queries of a 3-D IPC.

    Parameters
    ----------
    query : IPCQuery
        The one query path of a model whose ``y`` is 3-D.
    target : Box
        The landing target ``G`` the decision is taken against (3-D).

    Attributes
    ----------
    rule : LandingRule
        The decision rule for ``target``, also usable on ellipsoids from elsewhere.

    Examples
    --------
    >>> from ipcverify.network import ModelConfig
    >>> from ipcverify import example
    >>> untrained = example(config=ModelConfig.recipe("v1", x_dim=2, y_dim=3, hidden=(8,))).model
    >>> q = LandingQuery(IPCQuery(untrained), Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
    >>> d = q.decide([0.0, 1.0], [0.1, 0.2, 0.3])
    >>> d.verdict.name, d.accept, d.proven   # its sets are far too large to land on
    ('REJECT', False, False)
    """

    query: IPCQuery
    target: Box
    rule: LandingRule = field(init=False)

    def __post_init__(self) -> None:
        if not isinstance(self.query, IPCQuery):
            raise InvalidInputError(
                f"LandingQuery needs an IPCQuery (IPCQuery(model)); got {type(self.query).__name__}"
            )
        if not isinstance(self.target, Box) or self.target.dim != 3:
            raise SetError("the landing target must be a 3-D Box")
        n = self.query.model.config.y_dim
        if n != 3:
            raise SetError(f"the landing decision needs a 3-D ellipsoid; this model has n = {n}")
        object.__setattr__(self, "rule", LandingRule(self.target))
        landing_bound.prepare()  # the landing bound's compiled float tier

    @property
    def model(self) -> IPCModel:
        """The queried model."""
        return self.query.model

    def ellipsoid(self, x: ArrayLike, yhat: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Centre (3,) and calibrated shape (3, 3) of one query (:meth:`IPCQuery.ellipsoid`)."""
        return self.query.ellipsoid(x, yhat)

    def _moved(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform
    ) -> tuple[FloatArray, FloatArray, bool]:
        """The query's set moved by ``transform``, and the domain test's answer."""
        center, flat, inside = self.query.values(x, yhat)
        c, C = transform(*self.query.arrays(center, flat))
        return c, C, inside

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
        """
        if transform is None:  # no arrays until the answer is known
            center, flat, inside = self.query.values(x, yhat)
            if not inside:
                return self.rule.outside_domain_values(center, flat)
            return self.rule.decide_values(center, flat)
        c, C, inside = self._moved(x, yhat, transform)
        return self.rule.decide(c, C) if inside else self.rule.outside_domain(c, C)

    def decide_float(
        self, x: ArrayLike, yhat: ArrayLike, transform: Transform | None = None
    ) -> QueryDecision:
        """Query -> ellipsoid -> float landing decision (fast; **not a proof**).

        The rule of :func:`~ipcverify.decision.landing_slack`; near the threshold it may
        differ from the exact decision. Use :meth:`decide` when the answer steers the vehicle.
        """
        if transform is None:  # Python floats, as decide()
            center, flat, inside = self.query.values(x, yhat)
            if not inside:
                return self.rule.outside_domain_values(center, flat)
            return self.rule.decide_float_values(center, flat)
        c, C, inside = self._moved(x, yhat, transform)
        return self.rule.decide_float(c, C) if inside else self.rule.outside_domain(c, C)

    def __repr__(self) -> str:
        return f"LandingQuery({self.query!r}, target={self.target!r})"
