"""The outcome and method of a containment question: :class:`Status` and :class:`Method`.

Examples
--------
>>> Status.PROVEN.value, Method("sdp") is Method.SDP
('PROVEN', True)
"""

from __future__ import annotations

import json
from enum import Enum
from typing import Any

import numpy as np

from ipcverify.errors import InvalidInputError
from ipcverify.sets._outer import OuterSet


class Status(Enum):
    """Outcome of a containment proof; ``str(status)`` says what to do next.

    Examples
    --------
    >>> Status.UNKNOWN.advice.startswith("neither")
    True
    """

    PROVEN = "PROVEN"
    REFUTED = "REFUTED"
    UNKNOWN = "UNKNOWN"

    @property
    def advice(self) -> str:
        """What the status means for the caller and what to do next."""
        return _ADVICE[self]

    def __str__(self) -> str:
        return f"{self.value}: {self.advice}"


_ADVICE = {
    Status.PROVEN: (
        "the inner set is inside the outer set; the certificate re-verifies in exact "
        "rational arithmetic, so it may be relied on"
    ),
    Status.REFUTED: (
        "the inner set is NOT inside the outer set; the witness point lies in the inner "
        "set and outside the outer set (checked exactly): shrink the inner set or grow "
        "the outer set"
    ),
    Status.UNKNOWN: (
        "neither proven nor refuted (solver not optimal, or the sets are too close to "
        "touching for float multipliers); treat the containment as NOT established, or "
        "retry with another method or with a slightly larger outer set"
    ),
}


class Method(Enum):
    """How a containment was decided.

    ``closed-form`` (exact, the decision of record) and ``socp`` (a cross-check) apply to
    boxes and polytopes; ``sdp`` (the S-lemma, solved by Clarabel and re-checked exactly)
    applies to every outer set: one LMI for an ellipsoid, one per face for a box or polytope.
    """

    CLOSED_FORM = "closed-form"
    SOCP = "socp"
    SDP = "sdp"


def parse_method(v: Any, where: str) -> Method:
    """``Method(v)``, or an :class:`InvalidInputError` naming the field ``where`` and the choices."""
    try:
        return Method(v)
    except ValueError:
        names = ", ".join(m.value for m in Method)
        raise InvalidInputError(f"field '{where}': {json.dumps(v)[:40]} is not one of {names}") from None


def check_method(method: Method, outer: OuterSet) -> None:
    """Refuse a method that does not apply to the outer set (an ellipsoid needs ``sdp``).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box
    >>> from ipcverify.sets import Ellipsoid
    >>> check_method(Method.SOCP, Ellipsoid(np.zeros(1), np.eye(1)))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.InvalidInputError: method 'socp' does not apply to an ellipsoid outer set: ...
    >>> check_method(Method.SDP, Box([0.0], [1.0])) is None       # the S-lemma applies to every set
    True
    """
    if method.value not in outer.methods:
        article = "an" if outer.kind[:1] in "aeiou" else "a"
        use = " or ".join(f"'{m}'" for m in outer.methods)
        raise InvalidInputError(
            f"method '{method.value}' does not apply to {article} {outer.kind} outer set: "
            f"use {use} for {outer.kind}s; 'closed-form', 'socp' or 'sdp' for boxes and polytopes"
        )


def default_method(outer: OuterSet) -> Method:
    """The outer set's default method (the first of its ``methods``): ``sdp`` for an ellipsoid,
    ``closed-form`` for a box or polytope.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Ellipsoid
    >>> default_method(Ellipsoid(np.zeros(1), np.eye(1))).value
    'sdp'
    """
    return Method(outer.methods[0])


def solve_with_clarabel(problem: Any) -> str:
    """Solve a cvxpy problem with Clarabel; its status, or ``"solver error (...)"`` if Clarabel failed.

    Only ``"optimal"`` may lead to a proof; every other status (``optimal_inaccurate`` included)
    is UNKNOWN to the provers.
    """
    import cvxpy as cp  # imported on first use: it takes about a second

    try:
        with np.errstate(all="ignore"):
            problem.solve(solver=cp.CLARABEL)
        return str(problem.status)
    except cp.error.SolverError as exc:
        return f"solver error ({exc})"
